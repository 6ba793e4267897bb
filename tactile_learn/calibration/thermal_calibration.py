"""Calibration of a real thermal fingertip (heated and optional passive thermistor) from labelled touches.

The model (:mod:`synth.sensors.thermal_dynamics`, every term a verified closed form): each channel
is a lumped body (heat capacity ``C``, loss ``G``) read through two thermistor lags, touching the
object through a contact conductance ``H``; the object (a semi-infinite body of its class's
effusivity ``e`` and a contact patch of radius ``a``: spreading conductance ``4 k / (pi a)``) has
an unknown temperature, the same for both channels. The contact builds up over a ramp starting a
lead before the onset (the force's half-plateau crossing, or the curve's departure), each channel
may drift before contact (a heater still settling, the approach to a cold object), and the heater's
power changes at a delay after the onset: by ``-(G (R0 + r (tau_1 + tau_2) - T_amb) + C r)`` with a
fitted ``T_amb`` (a rig that switches its heater off on contact: ``T_amb`` is the ambient; a
controller that goes on heating: ``T_amb`` above the set point, a rise)::

    reading_c(t) = R0_c + r_c drift_c(t) + (R0_c + r_c (tau_1 + tau_2) - T_obj) obj_c(t)
                   - [heated] (G (R0 + r (tau_1 + tau_2) - T_amb) + C r) power(t - t_off)

The temperatures identify only ``e / C``, ``G / C`` and ``H / C``: each class's effusivity is fixed
at its library value (geometric mean over its materials), which sets the scale. Fitted (nonlinear,
multi-start ``scipy.optimize.least_squares``, trust region with bounds, short runs from jittered
starts, the best run to convergence): the heated channel's ``C, G, H``, the passive one's ``G`` and
its ``C`` and ``H`` as ratios to the heated twin's (within a factor 10 and 20: objects at the passive
thermistor's own temperature give it no signal, so its scale is barely seen), each channel's sum of
lags and its split (kept away from equal lags, a double root), the radius ``a``, the contact's lead
and ramp and the time of the heater's power change. Linear, solved exactly inside every evaluation (variable
projection): per touch ``R0_c, r_c, T_obj``, and the shared ``T_amb``, with weak priors that keep
them physical when a channel alone cannot pin them (``T_obj`` within ~25 K of the sensor, drifts of
a few tenths of K/s). Then every touch is refitted alone for its own contact (a conductance factor,
lead and ramp): their spread is the touch-to-touch variation a calibrated scene draws from. Last
(``touch_contact``), the shared parameters and every touch's own contact are refined together (a
press is never the same twice: a real user's touches have their own contact; weak priors tie them
to the shared one, with which they trade off), with a Jacobian that steps all touches' own
parameters at once (each moves its own touch's rows only). Optional per-touch nuisance terms
(``nuisance``, linear, closed forms in :func:`synth.sensors.thermal.dynamics.nuisance_terms`): the
object's flux (its temperature not uniform with depth), the heater's power steps, and a contact
precursor (part of the contact arriving over the ``PRECURSOR_S`` before it, one amplitude per
channel). Optional and nonlinear: the approach through the closing air gap (two shared parameters)
and contact events (``"contact_events"``: each channel's contact conductance steps by a bounded
factor at events placed at the kinks of the own-contact residual, :mod:`.thermal_events`; per-touch
parameters of the joint refinement). Optional too (``noise_weighted``): the joint refinement in
units of each sample's noise s.d. (the maximum-likelihood fit in the unit the residual is reported
in) with weak linear priors.

Noise (what a residual is measured against): the recorder adds white noise ``sigma_w`` (from the
pre-contact segment) and jitters its time stamps by ``sigma_t`` (estimated from how far each curve
strays from a smooth spline relative to its slope), so ``sigma(t)^2 = sigma_w^2 + (sigma_t dx/dt)^2``.
A second unit, ``precontact_k``, is the scatter of the segment before any contact about a quadratic
trend (the noise's whole per-sample variance, its correlated parts included); the report gives
both (``rms_sigma``, ``rms_sigma_precontact``), with each touch's own contact (the headline) and with
one shared contact (``shared_contact``).
The report gives the fit's residual in those units, every parameter with its bounds, the ones at a
bound (with the likely reason), and the ones the data do not identify (posterior s.d. above a factor
of 2, or a correlation above 0.99 with another).

This module drives the fit (:func:`calibrate_channels`); the pieces: the touches on the fitting grid
and the noise levels (:mod:`.thermal_touches`), the parameters and the fit's settings such as
``PRECURSOR_S`` or ``EVENT_FACTOR_MAX`` (:mod:`.thermal_parameters`), the least-squares problem
(:mod:`.thermal_problem`), the report (:mod:`.thermal_report`), the contact events' placement
(:mod:`.thermal_events`) and the residual's kinks (:mod:`.thermal_kinks`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import optimize

from synth.materials import Material
from tactile_learn.calibration.thermal_events import place_events
from tactile_learn.calibration.thermal_parameters import EVENT_FACTOR_MAX, NUISANCE_TERMS, Parameter
from tactile_learn.calibration.thermal_problem import CalibrationProblem
from tactile_learn.calibration.thermal_report import calibration_report, event_report, touch_bounds
from tactile_learn.calibration.thermal_touches import FIT_HZ, FitTouch, noise_levels, prepare_touches

__all__ = [
    "FIT_HZ",
    "NUISANCE_TERMS",
    "CalibrationResult",
    "FitTouch",
    "Parameter",
    "calibrate_channels",
    "noise_levels",
    "prepare_touches",
]

#: the joint refinement (shared + every touch's own contact) fits every sample in units of its
#: noise s.d. (white noise and timing jitter, see noise_levels), with weak priors (PRIOR_ROW_TOUCH_K):
#: the maximum-likelihood fit under the noise model the residual is reported in. Off, every sample
#: of both channels weighs the same in K (the passive channel's white noise is ~7 times smaller).
#: Off by default: on R_1 it lowers the residual in sigma (37 -> 30) by trading the heated channel's
#: mK for the passive one's (see docs/thermal-real.md, calibration)
NOISE_WEIGHTED = False
#: solver evaluations of the joint refinement (shared + every touch's own contact)
TOUCH_RUN = 40
#: solver evaluations of each multi-start's short run
SHORT_RUN = 15


@dataclass
class CalibrationResult:
    """The fitted values (by parameter name), per-touch values, the noise, and the report."""

    values: dict[str, float]
    per_touch: list[dict[str, float]]
    noise: dict[str, float]
    report: dict[str, Any] = field(default_factory=dict)


def calibrate_channels(
    touches: list[FitTouch],
    classes: Sequence[Sequence[Material]],
    noise: dict[str, dict[str, float]],
    *,
    starts: int = 8,
    seed: int = 0,
    heater_off: bool = True,
    nuisance: Sequence[str] = (),
    touch_contact: bool = True,
    noise_weighted: bool | None = None,
) -> CalibrationResult:
    """Multi-start fit of the model to ``touches`` (see the module docstring). ``nuisance``: the
    per-touch terms to fit, of :data:`NUISANCE_TERMS` (see
    :func:`synth.sensors.thermal.dynamics.nuisance_terms`); ``touch_contact``: after the shared
    fit, refine it jointly with every touch's own contact (conductance factor, lead, build-up)."""
    started = time.perf_counter()
    if noise_weighted is None:
        noise_weighted = NOISE_WEIGHTED
    refine_noise = noise if noise_weighted else None
    problem = CalibrationProblem(touches, classes, heater_off, nuisance)
    final, evaluations = _multi_start(problem, starts, seed)
    res, sol, values, lead, ramp = _solved(problem, final.x)
    spread, own_res = _touch_spread(touches, classes, heater_off, problem, final.x, refine_noise)
    shared_res = res
    if touch_contact:
        problem, final, more = _refine_jointly(problem, final.x, spread, lead, ramp, refine_noise)
        evaluations += more
        res, sol, values, lead, ramp = _solved(problem, final.x)
        own_res = res
        k = problem.n_free
        jac = np.asarray(final.jac)
        cov = np.linalg.pinv(jac.T @ jac) * float(np.mean(final.fun**2))
        for i, r in enumerate(spread):
            r["touch_conductance_factor"] = float(problem.h_scale[i])
            r["touch_conductance_sd_log"] = float(np.sqrt(max(cov[k + i, k + i], 0.0)))
            r["touch_lead_s"] = float(lead[i])
            r["touch_ramp_s"] = float(ramp[i])
    per_touch = _per_touch_rows(problem, sol, lead, ramp, spread)
    report = calibration_report(
        problem, final, shared_res, own_res, values, per_touch, noise, evaluations, time.perf_counter() - started
    )
    if problem.per_touch:
        report["touch_contact"] = touch_bounds(problem, final.x)
    if problem.event_t is not None:
        report["contact_events"] = event_report(problem, final)
    return CalibrationResult(values, per_touch, {**noise.get("heated", {})}, report)


def _multi_start(problem: CalibrationProblem, starts: int, seed: int) -> tuple[optimize.OptimizeResult, int]:
    """Short runs from the default start and random points of the (log) box, then the best one
    runs to convergence: the final run and the evaluations they all took."""
    lo, hi = problem.bounds()
    rng = np.random.default_rng(seed)
    base = problem.start()
    candidates = []
    evaluations = 0
    for s in range(starts):
        x0 = base.copy()
        if s:  # around the default: far corners of the box are unphysical and slow to leave
            x0 = base + rng.normal(0.0, 1.0, len(base)) * np.minimum(1.0, 0.25 * (hi - lo))
        fit = problem.fit_from(x0, SHORT_RUN)
        evaluations += int(fit.nfev)
        candidates.append(fit)
    best = min(candidates, key=lambda f: f.cost)
    final = problem.fit_from(best.x, 200)
    return final, evaluations + int(final.nfev)


def _solved(
    problem: CalibrationProblem, free: np.ndarray
) -> tuple[np.ndarray, np.ndarray, dict[str, float], np.ndarray, np.ndarray]:
    """The residuals, linear values, parameter values (the shared ambient among them where the
    heater's power change is fitted with one), leads and ramps of ``problem`` at ``free``."""
    res, sol, power_q = problem.solve(free)
    values, lead, ramp = problem.unpack(free)
    if problem.heater_off and "heater_steps" not in problem.nuisance:
        values["heater.ambient_c"] = power_q
    return res, sol, values, lead, ramp


def _refine_jointly(
    problem: CalibrationProblem,
    shared: np.ndarray,
    spread: list[dict[str, float]],
    lead: np.ndarray,
    ramp: np.ndarray,
    noise: dict[str, dict[str, float]] | None,
) -> tuple[CalibrationProblem, optimize.OptimizeResult, int]:
    """The joint refinement: shared parameters and every touch's own contact (and its contact
    events, when fitted) together, from the shared fit ``shared`` and the touches' own refits
    ``spread``; the refined problem, its fit and the evaluations it took."""
    problem = problem.with_touch_contact(noise)
    x0 = np.concatenate(
        [
            shared,
            [math.log(r["touch_conductance_factor"]) for r in spread],
            [r["touch_lead_s"] - float(lead[0]) for r in spread],
            [math.log(r["touch_ramp_s"] / float(ramp[0])) for r in spread],
        ]
    )
    if "contact_events" in problem.nuisance:  # placed at the kinks of every touch's own-contact residual
        times, logs = place_events(problem, x0, FIT_HZ, shared=problem.event_channels() == ("both",))
        problem = problem.with_events(times).with_touch_contact(noise)
        bound = math.log(EVENT_FACTOR_MAX) * (1 - 1e-3)
        event_x0: list[np.ndarray] = []
        for k in range(logs.shape[2]):  # per slot: each channel's log factor, then the shift (0)
            event_x0 += [np.clip(logs[c, :, k], -bound, bound) for c in range(logs.shape[0])]
            event_x0.append(np.zeros(problem.n))
        x0 = np.concatenate([x0, *event_x0])
    lo, hi = problem.bounds()
    final = optimize.least_squares(
        problem.residuals,
        np.clip(x0, lo + 1e-9, hi - 1e-9),
        jac=problem.jacobian,
        bounds=(lo, hi),
        x_scale="jac",
        max_nfev=TOUCH_RUN,
    )
    evaluations = int(final.nfev) + int(final.njev or 0) * (problem.n_free + len(problem.per_touch))
    return problem, final, evaluations


def _per_touch_rows(
    problem: CalibrationProblem, sol: np.ndarray, lead: np.ndarray, ramp: np.ndarray, spread: list[dict[str, float]]
) -> list[dict[str, float]]:
    """Every touch's row of the report: its contact, object temperature, own contact (``spread``),
    each channel's onset value and drift, and its nuisance terms' amplitudes."""
    per_touch = []
    n_ch = 2 if problem.passive else 1
    for i in range(problem.n):
        row: dict[str, float] = {"lead_s": float(lead[i]), "ramp_s": float(ramp[i]), "object_c": float(sol[i, -1])}
        row.update(spread[i])
        row["heated_onset_c"] = float(sol[i, 0])
        row["heated_drift_k_s"] = float(sol[i, 1])
        if n_ch == 2:
            row["passive_onset_c"] = float(sol[i, 2])
            row["passive_drift_k_s"] = float(sol[i, 3])
        for j, name in enumerate(problem.nuisance_columns):
            row[name] = float(sol[i, 2 * n_ch + j])
        per_touch.append(row)
    return per_touch


def _touch_spread(
    touches: list[FitTouch],
    classes: Sequence[Sequence[Material]],
    heater_off: bool,
    problem: CalibrationProblem,
    shared: np.ndarray,
    noise: dict[str, dict[str, float]] | None = None,
) -> tuple[list[dict[str, float]], np.ndarray]:
    """How much the touches differ: each touch refitted alone for its contact (a conductance
    factor, the lead and the build-up time), everything else at the shared fit. Their spread is
    what a calibrated scene draws from (a press is never quite the same twice). Also returns the
    residuals (C, n, W) of every touch with its own contact (0 outside its record)."""
    names = [p.name for p in problem.shared]
    i_lead, i_ramp = names.index("contact.lead_s"), names.index("contact.ramp_s")
    rows = []
    own = np.zeros((2 if problem.passive else 1, problem.n, problem.length))
    for i, tc in enumerate(touches):
        single = CalibrationProblem([tc], classes, heater_off, problem.nuisance, noise)

        def residuals(theta: np.ndarray, single: CalibrationProblem = single) -> np.ndarray:
            single.h_scale = np.array([math.exp(theta[0])])
            x = shared.copy()
            x[i_lead], x[i_ramp] = theta[1], theta[2]
            return single.residuals(x)

        lead_p, ramp_p = problem.shared[i_lead], problem.shared[i_ramp]
        lo = np.array([math.log(0.1), lead_p.to_free(lead_p.lo), ramp_p.to_free(ramp_p.lo)])
        hi = np.array([math.log(10.0), lead_p.to_free(lead_p.hi), ramp_p.to_free(ramp_p.hi)])
        x0 = np.clip(np.array([0.0, shared[i_lead], shared[i_ramp]]), lo + 1e-6, hi - 1e-6)
        fit = optimize.least_squares(residuals, x0, bounds=(lo, hi), x_scale="jac", max_nfev=40, diff_step=1e-5)
        jac = np.asarray(fit.jac)
        s2 = float(np.mean(fit.fun**2))
        # the factor's posterior s.d. (log): a wood at room temperature barely depends on H
        cov = np.linalg.pinv(jac.T @ jac) * s2
        residuals(fit.x)  # sets the touch's own conductance factor
        x_own = shared.copy()
        x_own[i_lead], x_own[i_ramp] = fit.x[1], fit.x[2]
        res_own = single.solve(x_own)[0][:, 0]
        own[:, i, : res_own.shape[1]] = res_own
        rows.append(
            {
                "touch_conductance_factor": math.exp(float(fit.x[0])),
                "touch_conductance_sd_log": float(np.sqrt(max(cov[0, 0], 0.0))),
                "touch_lead_s": float(fit.x[1]),
                "touch_ramp_s": ramp_p.from_free(float(fit.x[2])),
                "touch_rms_k": float(np.sqrt(np.mean(res_own[:, single.mask[0]] ** 2))),
            }
        )
    return rows, own
