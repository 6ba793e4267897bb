"""Where a touch's contact events are: kinks in its residual placed by the step they would cause.

A step of the contact conductance does not kink the reading at once: the thermistor's lags bend
it over tenths of a second, so a kink in the residual (:mod:`tactile_learn.calibration.thermal_kinks`)
comes 0.15-0.35 s after its event, and a linear refit of the touch's temperatures around a missing
step adds bends of its own. :func:`place_events` therefore only takes a kink as the sign that an
event is near (the gate: no kink of at least ``THRESHOLD_K_S``, no event: a touch whose residual is
smooth gets none) and places the event where the step's own response (both channels at once, the
touch's linear terms projected out: what the fit could not absorb) explains the residual best,
among times from ``BEFORE_S`` before the kink to ``AFTER_S`` after it; the step is then taken out
and the next kink looked for (matching pursuit, at most ``MAX_EVENTS`` per touch). Each channel's
step size comes from the same least squares: the starting factors of the joint refinement.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from synth.sensors.thermal.contact_events import contact_event_terms
from tactile_learn.calibration.thermal_kinks import HALF_S, kink_indices, slope_change

if TYPE_CHECKING:
    from tactile_learn.calibration.thermal_problem import CalibrationProblem

__all__ = ["place_events"]

#: an event is looked for from this long before its kink ...
BEFORE_S = 0.6
#: ... to this long after it (s), in steps of STEP_S
AFTER_S = 0.2
STEP_S = 0.05
#: at most this many events per touch
MAX_EVENTS = 6
#: a kink this close to a placed event is that event's (s)
NEAR_S = 0.4
#: the template's factor (its response is linear in log f to ~1 % there)
_PROBE = 1.02


def _templates(problem: CalibrationProblem, free: np.ndarray, i: int, taus: np.ndarray) -> np.ndarray:
    """Per channel and candidate time, the reading's change per unit log factor of a step at ``taus``
    (s after touch ``i``'s onset), its object term only: (C, K, W) on the touch's samples."""
    values, lead, ramp = problem.unpack(free)
    radius = values["contact.radius_mm"] * 1e-3
    e = problem.class_e[problem.label]
    spreading = 4.0 * e * np.sqrt(problem.class_alpha[problem.label]) / (math.pi * radius)
    rows = np.full(len(taus), i)
    t_rel = np.repeat((problem.t[i] - (problem.onset[i] - lead[i]))[None, :], len(taus), axis=0)
    out = []
    for ch in ("heated", "passive") if problem.passive else ("heated",):
        model = problem.channel_model(values, ch, e, spreading)._rows(rows)
        at = np.maximum(taus + lead[i], 0.0)[:, None]
        ev = contact_event_terms(model, t_rel, np.full(len(taus), ramp[i]), at, np.full((len(taus), 1), _PROBE))
        out.append(ev.obj[:, problem.mask[i]] / math.log(_PROBE))
    return np.stack(out)


def place_events(
    problem: CalibrationProblem, free: np.ndarray, fs: float, shared: bool = False
) -> tuple[list[list[float]], np.ndarray]:
    """Every touch's events (s after its onset) and each channel's starting log factor per event,
    (C, n, K) with K the most events of a touch (0 where a touch has fewer; ``shared``: one factor
    for both channels, (1, n, K)). ``problem`` at ``free`` without events; ``fs`` the fitting
    grid's rate."""
    res, sol, _ = problem.solve(free)
    cols, _, extra = problem.design(free)
    values, _, _ = problem.unpack(free)
    channels = ("heated", "passive") if problem.passive else ("heated",)
    n_side = max(round(HALF_S * fs), 2)
    times: list[list[float]] = []
    sizes: list[list[np.ndarray]] = []
    for i in range(problem.n):
        keep = problem.mask[i]
        tt = problem.t[i][keep] - problem.onset[i]
        current = -res[:, i, keep]  # data minus model
        # the touch's linear terms per channel (R0, drift, T_obj, nuisance): what a refit absorbs
        basis = [np.concatenate([cols[c, i, keep], extra[c, i, keep]], axis=1) for c in range(len(channels))]
        v0 = [
            sol[i, 2 * c] + sol[i, 2 * c + 1] * (values[f"{ch}.lag_s"] + values[f"{ch}.lag2_s"]) - sol[i, -1]
            for c, ch in enumerate(channels)
        ]
        placed: list[float] = []
        steps: list[np.ndarray] = []
        while len(placed) < MAX_EVENTS:
            found = []
            for c in range(len(channels)):
                change = slope_change(tt, current[c], n_side)
                found += [(abs(float(change[k])), float(tt[k])) for k in kink_indices(tt, change)]
            found = [f for f in found if all(abs(f[1] - p) > NEAR_S for p in placed)]
            if not found:
                break
            kink = max(found)[1]
            taus = np.arange(kink - BEFORE_S, kink + AFTER_S + 1e-9, STEP_S)
            taus = taus[taus > 0.1]
            shapes = _templates(problem, free, i, taus) * np.array(v0)[:, None, None]
            best, best_gain, best_fit = 0, -1.0, None
            for k in range(len(taus)):
                proj = [
                    shapes[c, k] - basis[c] @ np.linalg.lstsq(basis[c], shapes[c, k], rcond=None)[0]
                    for c in range(len(channels))
                ]
                norms = np.array([float(col @ col) for col in proj])
                dots = np.array([float(col @ current[c]) for c, col in enumerate(proj)])
                if shared:  # one amplitude for both channels
                    a_all = np.full(len(channels), dots.sum() / max(norms.sum(), 1e-300))
                else:
                    a_all = np.where(norms > 0, dots / np.where(norms > 0, norms, 1.0), 0.0)
                fit = list(zip(a_all.tolist(), proj, strict=True))
                gain = float(np.sum(2 * a_all * dots - a_all**2 * norms))  # the drop of the squared residual
                if gain > best_gain:
                    best, best_gain, best_fit = k, gain, fit
            assert best_fit is not None
            placed.append(float(taus[best]))
            steps.append(np.array([a for a, _ in best_fit]))
            for c, (a, col) in enumerate(best_fit):
                current[c] = current[c] - a * col
        order = np.argsort(placed)
        times.append([placed[k] for k in order])
        sizes.append([steps[k] for k in order])
    slots = max((len(row) for row in times), default=0)
    logs = np.zeros((1 if shared else len(channels), problem.n, slots))
    for i, row in enumerate(sizes):
        for k, step in enumerate(row):
            logs[:, i, k] = step[: logs.shape[0]]
    return times, logs
