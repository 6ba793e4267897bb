"""The approach: heat exchanged across the closing air gap before a channel touches its object.

Before the force rises the pad is already a fraction of a millimetre from the object, and heat
flows through the thinning air gap. A channel whose own contact conductance is ``H`` (its
thermistor behind its skin) sees, with the gap ``d(tau) = v (-tau)`` closing at the approach speed
``v`` until the contact at ``tau = 0``, and ``g0`` an effective residual gap (roughness, flatness)::

    h(tau) = 1 / (1 / H + (g0 + v (-tau)) / k_air),     -window <= tau < 0

(``k_air`` = 0.026 W/(m K), the handbook's value near room temperature; 0 before the window).
``h <= H`` always, and ``h -> 1 / (1 / H + g0 / k_air)`` at the contact: no free amplitude, the
precursor's size follows from the object's temperature (``V0``), its effusivity and the gap.

The exchange is solved as a Volterra equation for the gap flux ``q`` (out of the body, into the
object) by product integration on a uniform grid (piecewise-constant flux per cell, the cell's
mean gap conductance in closed form): the body (an open-loop lumped body ``1 / (C s + G)``, read
through the thermistor's lags) and the object's surface (``1 / (s (e sqrt s + k_s))``) answer a
flux step in closed form, so ``q_k = h_k (1 - sum_{j<k} q_j W_{k-j}) / (1 + h_k S(dt / 2))`` per
unit ``V0``. After the contact (a linear system again) the disturbance the gap left in the body and
the object drives the contact like a change of the temperature difference ``f(t)``: the reading is
its free tail plus Duhamel's integral of the contact's own step response (:func:`channel_terms`'
``obj``) over ``f``. The result is checked against a finite-volume solution with the gap
conductance varying in time (``tests/synth/sensors/test_thermal_approach.py``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal, special

from synth.errors import InputError
from synth.sensors.thermal.dynamics import ChannelModel, _split_lags, channel_terms

__all__ = ["K_AIR_W_MK", "approach_term", "gap_conductance"]

#: thermal conductivity of still air near room temperature (W/(m K)); handbook value
K_AIR_W_MK = 0.026


def gap_conductance(
    tau: np.ndarray, conductance: np.ndarray, gap_m: float, speed_m_s: float, window_s: float
) -> np.ndarray:
    """``h(tau)`` (B, T) for times ``tau`` (B, T) relative to the contact and contact conductances
    ``conductance`` (B,): the closing gap in series with the channel's own contact (0 outside the
    window before the contact)."""
    tt = np.asarray(tau, dtype=np.float64)
    r_contact = 1.0 / np.asarray(conductance, dtype=np.float64)[:, None]
    h = 1.0 / (r_contact + (gap_m + speed_m_s * np.maximum(-tt, 0.0)) / K_AIR_W_MK)
    return np.where((tt < 0) & (tt >= -window_s), h, 0.0)


def _mean_gap_conductance(
    start: np.ndarray, stop: np.ndarray, conductance: np.ndarray, gap_m: float, speed_m_s: float
) -> np.ndarray:
    """Mean of ``h`` over cells ``[start, stop]`` (T,) before the contact, (B, T): the integral of
    ``1 / (a + b s)`` over ``s = -tau`` is ``ln((a + b s_1) / (a + b s_0)) / b``."""
    a = (1.0 / conductance)[:, None] + gap_m / K_AIR_W_MK
    b = speed_m_s / K_AIR_W_MK
    s0, s1 = -stop[None, :], -start[None, :]
    return np.log1p(b * (s1 - s0) / (a + b * s0)) / (b * (s1 - s0))


def _flux_step_responses(model: ChannelModel, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per W/m^2 of a flux step out of the body and into the object at ``t = 0``, at times ``t``
    (T,) >= 0, (B, T) each: the body's drop, the reading's drop (through the lags) and the object
    surface's rise. Open loop (no controller) only."""
    c, g = model.heat_capacity[:, None], model.loss[:, None]
    tt = t[None, :]
    a0 = g / c
    body = -np.expm1(-a0 * tt) / g  # (1 - e^{-G t / C}) / G
    lag1, lag2 = _split_lags(model.lag1_s, model.lag2_s)
    rates = [a0[:, 0]]
    for tau in (lag1, lag2):
        rates.append(np.where(tau > 0, 1.0 / np.where(tau > 0, tau, 1.0), np.inf))
    # a body pole equal to a lag's is moved by 1e-4 of itself (the curve moves by ~1e-4 of itself)
    for j in (1, 2):
        close = np.abs(rates[j] - rates[0]) < 1e-4 * rates[0]
        rates[j] = np.where(close, rates[j] * (1 + 1e-4), rates[j])
    if np.isfinite(rates[1]).all() and np.isfinite(rates[2]).all():
        close = np.abs(rates[2] - rates[1]) < 1e-4 * rates[1]
        rates[2] = np.where(close, rates[2] * (1 + 1e-4), rates[2])
    # step response of prod a_j / (s + a_j) (a_0 = G / C, the lags' 1 / tau; an absent lag is
    # infinitely fast): 1 - sum_i prod_{j != i} a_j / (a_j - a_i) e^{-a_i t}; times 1 / G
    reading = np.ones((len(model), len(t)))
    for i in range(3):
        if not np.isfinite(rates[i]).any():
            continue
        coef = np.ones(len(model))
        for j in range(3):
            if j != i:
                fast = ~np.isfinite(rates[j])
                coef = coef * np.where(fast, 1.0, rates[j] / np.where(fast, 1.0, rates[j] - rates[i]))
        live = np.isfinite(rates[i])
        reading -= np.where(live[:, None], coef[:, None] * np.exp(-np.where(live, rates[i], 0.0)[:, None] * tt), 0.0)
    reading = reading / g
    # object: 1 / (s (e sqrt s + k_s)) -> (sqrt t / e) (1 - erfcx(y)) / y, y = k_s sqrt t / e
    e, ks = model.effusivity[:, None], model.spreading[:, None]
    y = ks * np.sqrt(tt) / e
    small = y < 1e-6
    ratio = np.where(small, 2.0 / math.sqrt(math.pi) - y, -special.erfcx(y) / np.where(small, 1.0, y))
    ratio = np.where(small, ratio, ratio + 1.0 / np.where(small, 1.0, y))
    surface = np.sqrt(tt) / e * ratio
    return body, reading, surface


def approach_term(
    model: ChannelModel,
    t: np.ndarray,
    ramp_s: np.ndarray | float,
    gap_m: float,
    speed_m_s: float,
    window_s: float = 2.0,
    fs: float = 50.0,
) -> np.ndarray:
    """The approach's part of the reading per kelvin of ``V0`` (the body's pre-contact temperature
    minus the object's), (B, T) at times ``t`` (B, T) relative to the contact (see the module
    docstring): add it to :func:`channel_terms`' ``obj``. 0 before the window; before the contact
    it is the gap's cooling read through the lags; after it the gap's after-effect.

    ``fs`` (Hz): the quadrature's grid (the gap's time scale ``g0 / v`` and the lags are resolved
    at 50 Hz to ~0.1 %% of the term). Open-loop channels only (the calibration's model)."""
    if (model.kp > 0).any() or (model.ki > 0).any():
        raise InputError("approach_term: a channel with a heater controller is not supported (open loop only)")
    for name, value in (("gap_m", gap_m), ("speed_m_s", speed_m_s), ("window_s", window_s), ("fs", fs)):
        if not (math.isfinite(value) and value > 0):
            raise InputError(f"{name}: must be finite and > 0")
    tt = np.asarray(t, dtype=np.float64)
    tt = np.broadcast_to(tt, (len(model), tt.shape[-1]))
    dt = 1.0 / fs
    n_pre = max(round(window_s * fs), 1)
    n_post = max(math.ceil(float(tt.max()) * fs) + 1, 1)
    edges = (np.arange(-n_pre, n_post + 1)) * dt  # grid edges, the contact at index n_pre
    h_cell = _mean_gap_conductance(edges[:n_pre], edges[1 : n_pre + 1], model.conductance, gap_m, speed_m_s)
    lags = np.arange(len(edges) + 1) * dt
    body, reading, surface = _flux_step_responses(model, lags)
    both = body + surface
    # the gap phase: Volterra of the second kind, piecewise-constant flux, driving difference at mid-cell
    half = _flux_step_responses(model, (np.arange(n_pre) + 0.5) * dt)
    both_mid = half[0] + half[2]  # S((m + 1/2) dt), m = 0..n_pre-1
    w_mid = np.diff(both_mid, axis=1, prepend=0.0)  # W_m = S((m + 1/2) dt) - S((m - 1/2) dt); W_0 = S(dt/2)
    q = np.zeros((len(model), n_pre))
    for k in range(n_pre):
        past = (q[:, :k] * w_mid[:, k:0:-1]).sum(axis=1) if k else 0.0
        q[:, k] = h_cell[:, k] * (1.0 - past) / (1.0 + h_cell[:, k] * w_mid[:, 0])
    # every grid edge: the reading's drop and the driving difference's change, from the gap flux
    d_reading = np.diff(reading, axis=1)  # D[m] = S(m dt) - S((m - 1) dt), m >= 1
    d_both = np.diff(both, axis=1)
    n_edges = len(edges)
    tail = -signal.fftconvolve(q, d_reading[:, :n_edges], axes=1)[:, :n_edges]
    drive = -signal.fftconvolve(q, d_both[:, :n_edges], axes=1)[:, :n_edges]
    # shift: the flux of cell j reaches edge n with D[n - j]; fftconvolve's index n pairs q_j, D_{n-j}
    # with D[m] stored at m - 1: edge n = index n - 1
    tail = np.concatenate([np.zeros((len(model), 1)), tail[:, :-1]], axis=1)
    drive = np.concatenate([np.zeros((len(model), 1)), drive[:, :-1]], axis=1)
    # after the contact: Duhamel of the contact's step response over f (trapezoid per cell)
    post = edges[n_pre:]
    obj = channel_terms(model, post[None, :].repeat(len(model), axis=0), ramp_s).obj  # obj at m dt, m >= 0
    f = drive[:, n_pre:]
    df = np.diff(f, axis=1)
    obj_mid = 0.5 * (obj[:, 1:] + obj[:, :-1])  # obj((m + 1/2) dt) by the trapezoid
    duhamel = f[:, :1] * obj + np.concatenate(
        [np.zeros((len(model), 1)), signal.fftconvolve(df, obj_mid, axes=1)[:, : len(post) - 1]], axis=1
    )
    out_grid = tail.copy()
    out_grid[:, n_pre:] += duhamel
    result = np.empty(tt.shape)
    for i in range(len(model)):
        result[i] = np.interp(tt[i], edges, out_grid[i], left=0.0)
    return result
