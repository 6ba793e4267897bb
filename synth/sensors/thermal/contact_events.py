"""Contact events: the contact conductance changes in steps while the contact holds.

A pad pressed on an object does not keep one contact: it slips or creeps, and the real contact
area (and with it the contact conductance ``H``) changes in a few steps while the force stays put.
Heat then flows differently from that instant on, and the reading's slope changes (a kink). With
``H(t) = H0 m(t)``, ``m`` piecewise constant (1 until the first event, then the product of the
events' factors so far), and ``q0`` the contact flux of the constant-``H0`` model (closed forms:
:func:`synth.sensors.thermal.dynamics.channel_terms`), the extra flux ``p = q - q0`` out of the
body and into the object obeys the Volterra equation of the second kind

    p(t) = (m(t) - 1) q0(t) - H0 m(t) (K * p)(t),

``K`` the open (uncoupled) body's and object surface's flux-step responses (the same kernels as
the approach: :mod:`synth.sensors.thermal.approach`). It is solved by product integration on a
uniform grid that starts at the first event (piecewise-constant ``p`` per cell, collocation at the
cell's middle, ``m`` averaged over each cell, so an event between grid points costs no accuracy
order); the reading moves by ``-(Read * p)``, ``Read`` the body's flux-step response seen through
the thermistor's lags. ``q0`` per kelvin of ``V0`` is ``H0 (1 + (T_b - T_i))`` with the body's and
the interface's deviations in closed form (``-H (C s + G + Z) / (s D)``, ``Z`` the object's
admittance), averaged over the contact's build-up like ``obj``; per W/m^2 of a heater power step it
is ``H0 Z / (s D)``. The terms are exact for a contact whose build-up has ended at the first event
(the calibration looks for events after 0.8 s; build-ups are tenths of a second) and checked
against a finite-volume solution whose contact conductance steps in time
(``tests/synth/sensors/test_thermal_contact_events.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

from synth.errors import InputError
from synth.sensors.thermal.approach import _flux_step_responses
from synth.sensors.thermal.dynamics import (
    ChannelModel,
    _evaluate,
    _pad_to,
    _poles,
    _poly_mul,
    _ramp_averaged,
    _split_lags,
)

__all__ = ["EventTerms", "conductance_multiplier", "contact_event_terms"]


@dataclass(frozen=True)
class EventTerms:
    """What the events add to :func:`~synth.sensors.thermal.dynamics.channel_terms`' curves, (B, T)
    each: ``obj`` per kelvin of ``V0``, ``heating`` per W/m^2 of a heater power step at the onset
    (a drift's net heating is ``C r`` of it), ``power`` per W/m^2 of a step at ``t_power`` (or None)."""

    obj: np.ndarray
    heating: np.ndarray
    power: np.ndarray | None


def conductance_multiplier(t: np.ndarray, event_t: np.ndarray, event_factor: np.ndarray) -> np.ndarray:
    """``m(t)`` (B, T): the product of the factors of the events (B, K) before ``t`` (B, T); an
    event time of NaN is no event."""
    live = np.isfinite(event_t)
    log_f = np.where(live, np.log(event_factor), 0.0)
    after = np.asarray(t)[:, :, None] > np.where(live, event_t, np.inf)[:, None, :]
    return np.exp((after * log_f[:, None, :]).sum(axis=2))


def _validate(event_t: np.ndarray, event_factor: np.ndarray, rows: int) -> tuple[np.ndarray, np.ndarray]:
    times = np.atleast_2d(np.asarray(event_t, dtype=np.float64))
    factors = np.atleast_2d(np.asarray(event_factor, dtype=np.float64))
    if times.shape != factors.shape or times.shape[0] != rows:
        raise InputError(f"event_t {times.shape} and event_factor {factors.shape}: must both be (B={rows}, K)")
    live = np.isfinite(times)
    if np.isinf(times).any():
        raise InputError("event_t: must be finite (NaN for no event)")
    if (live & ~(np.isfinite(factors) & (factors > 0))).any():
        raise InputError("event_factor: must be finite and > 0 for every event")
    if (live & (times < 0)).any():
        raise InputError("event_t: an event must come after the contact onset (t >= 0)")
    return times, factors


def _cell_mean_multiplier(start: np.ndarray, dt: float, times: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """Mean of ``m`` over cells ``[start, start + dt]`` (B, N): each event raises the product from
    its time on, so a cell holding an event gets the overlap-weighted mean of both values."""
    order = np.argsort(np.where(np.isfinite(times), times, np.inf), axis=1)
    t_sorted = np.take_along_axis(times, order, axis=1)
    f_sorted = np.take_along_axis(np.where(np.isfinite(times), factors, 1.0), order, axis=1)
    level = np.cumprod(f_sorted, axis=1)
    before = np.concatenate([np.ones((len(times), 1)), level[:, :-1]], axis=1)
    out = np.ones(start.shape)
    for k in range(times.shape[1]):
        live = np.isfinite(t_sorted[:, k])
        share = np.clip((start + dt - np.where(live, t_sorted[:, k], np.inf)[:, None]) / dt, 0.0, 1.0)
        out += share * (level[:, k] - before[:, k])[:, None]
    return out


def _lag_poly(model: ChannelModel) -> np.ndarray:
    """``Lq = (1 + tau_1 q^2)(1 + tau_2 q^2)`` (the present lags; split as in the channel model)."""
    b = len(model)
    lq = np.ones((b, 1))
    for tau in _split_lags(model.lag1_s, model.lag2_s):
        if (tau > 0).all():
            lq = _poly_mul(lq, np.stack([tau, np.zeros(b), np.ones(b)], axis=1))
    return lq


def _contact_fluxes(model: ChannelModel, t: np.ndarray, ramp: np.ndarray, t_power: np.ndarray | None) -> np.ndarray:
    """The constant-``H0`` model's contact flux (out of the body), (3, B, T) at times ``t`` (B, T):
    per kelvin of ``V0`` (the build-up averaged), per W/m^2 of a power step at the onset and at
    ``t_power`` (zeros without it). One structure of rows (see ChannelModel.structure)."""
    b = len(model)
    _, _, den = model._polynomials()
    h = model.conductance
    lq = _lag_poly(model)
    c, g, e, ks = model.heat_capacity, model.loss, model.effusivity, model.spreading
    # T_b - T_i per V0 (no lag): -H (C q^2 + e q + G + k_s) / (q^2 body) = -H (..) Lq / (q^2 D*)
    diff = _poly_mul(-h[:, None] * np.stack([c, e, g + ks], axis=1), lq)
    # flux per W/m^2 of a power step: H Z / (q^2 body) = H Z Lq / (q^2 D*)
    power = _poly_mul(h[:, None] * np.stack([e, ks], axis=1), lq)
    if (model.ki > 0).any() or (model.kp > 0).any():
        raise InputError("contact events: a channel with a heater controller is not supported (open loop only)")
    width = den.shape[1] - 1
    r, (w_diff, w_power) = _poles(np.stack([_pad_to(diff, width), _pad_to(power, width)]), den)
    safe = np.where(ramp > 0, ramp, 1.0)[:, None]
    built = np.where(ramp[:, None] > 0, np.clip(t / safe, 0.0, 1.0), (t > 0).astype(float))
    out = np.zeros((3, b, t.shape[1]))
    out[0] = h[:, None] * (built + _ramp_averaged(r, w_diff, t, ramp))
    out[1] = _evaluate(r, w_power, t)
    if t_power is not None:
        out[2] = _evaluate(r, w_power, t - t_power[:, None])
    return out


def contact_event_terms(
    model: ChannelModel,
    t: np.ndarray,
    ramp_s: np.ndarray | float,
    event_t: np.ndarray,
    event_factor: np.ndarray,
    t_power: np.ndarray | None = None,
    fs: float = 50.0,
) -> EventTerms:
    """The events' part of the reading (see the module docstring) at times ``t`` (B, T) after the
    contact onset: add each curve to :func:`~synth.sensors.thermal.dynamics.channel_terms`' (``obj``
    to ``obj``, ``C heating`` to ``drift``, ``power`` to ``power``). ``event_t`` (B, K): each event's
    time after the onset (NaN: none), ``event_factor`` (B, K): the contact conductance's factor at
    it; ``ramp_s`` the contact's build-up (B,); ``t_power`` (B,) a heater step's time; ``fs`` (Hz)
    the quadrature's grid (0.01-0.02 % of the term against the finite-volume solution at 25-50 Hz).
    0 before the first event. Open loop only."""
    if not (math.isfinite(fs) and fs > 0):
        raise InputError("fs: must be finite and > 0")
    b = len(model)
    tt = np.broadcast_to(np.asarray(t, dtype=np.float64), (b, np.asarray(t).shape[-1]))
    ramp = np.broadcast_to(np.asarray(ramp_s, dtype=np.float64), (b,))
    times, factors = _validate(event_t, event_factor, b)
    t_pow = None if t_power is None else np.broadcast_to(np.asarray(t_power, dtype=np.float64), (b,))
    out = np.zeros((3, b, tt.shape[1]))
    active = np.isfinite(times).any(axis=1)
    if not active.any():
        return EventTerms(out[0], out[1], None if t_pow is None else out[2])
    dt = 1.0 / fs
    first = np.where(active, np.min(np.where(np.isfinite(times), times, np.inf), axis=1), 0.0)
    n = max(math.ceil(float((tt.max(axis=1) - first)[active].max()) * fs) + 1, 1)
    cells = first[:, None] + np.arange(n)[None, :] * dt  # cell starts, per row
    m = _cell_mean_multiplier(cells, dt, times, factors)
    codes = model.structure()
    for code in np.unique(codes[active]):
        rows = np.flatnonzero((codes == code) & active)
        part = model._rows(rows)
        q0 = _contact_fluxes(part, cells[rows] + 0.5 * dt, ramp[rows], None if t_pow is None else t_pow[rows])
        body, _, surface = _flux_step_responses(part, (np.arange(n + 1) + 0.5) * dt)
        kernel = np.diff(body + surface, axis=1, prepend=0.0)[:, :n]  # W_0 = S(dt/2), W_k = S((k+1/2)dt) - ..
        h0m = part.conductance[:, None] * m[rows]  # (R, N)
        src = (m[rows] - 1.0)[None] * q0  # (3, R, N)
        p = np.zeros_like(src)
        for j in range(n):
            past = (p[:, :, :j] * kernel[None, :, j:0:-1]).sum(axis=2) if j else 0.0
            p[:, :, j] = (src[:, :, j] - h0m[None, :, j] * past) / (1.0 + h0m[None, :, j] * kernel[None, :, 0])
        # the reading at the grid's edges: every cell's flux step on and off, through the lags
        _, step_reading, _ = _flux_step_responses(part, np.arange(n + 1) * dt)
        d_read = np.diff(step_reading, axis=1)  # D[k - 1] = Read(k dt) - Read((k - 1) dt), k >= 1
        edges = np.zeros((3, len(rows), n + 1))
        for s in range(3):
            edges[s, :, 1:] = -signal.fftconvolve(p[s], d_read[:, :n], axes=1)[:, :n]
        grid = first[rows, None] + np.arange(n + 1)[None, :] * dt
        for i, row in enumerate(rows):
            for s in range(3):
                out[s, row] = np.interp(tt[row], grid[i], edges[s, i], left=0.0)
    return EventTerms(out[0], out[1], None if t_pow is None else out[2])
