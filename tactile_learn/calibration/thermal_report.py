"""The thermal calibration's report: every parameter with its bounds, posterior s.d. and whether the
data identify it (and why one sits at a bound), the residual in noise sigma (each touch with its own
contact and with one shared contact, its kinks and its windows in time), every touch's own contact
at its bounds and the contact events. :func:`~.thermal_calibration.calibrate_channels` writes it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from scipy import optimize

from tactile_learn.calibration.thermal_kinks import residual_kinks, residual_windows
from tactile_learn.calibration.thermal_parameters import EVENT_FACTOR_MAX, NUISANCE_DOC, SHARED_TERMS
from tactile_learn.calibration.thermal_problem import CalibrationProblem
from tactile_learn.calibration.thermal_touches import FIT_HZ

__all__ = ["UNIDENTIFIED_LOG_SD", "calibration_report", "event_report", "residual_summary", "touch_bounds"]

#: a parameter whose log s.d. exceeds this (a factor 2) is reported as not identified
UNIDENTIFIED_LOG_SD = math.log(2.0)

_BOUND_REASONS = {
    ("lag_share", "upper"): "one lag is enough: the second pole is faster than the samples resolve (tau_2 < 1 %)",
    ("lag_share", "lower"): "two equal lags (kept 4 % apart: equal lags are a double root)",
    ("ramp_s", "lower"): "the contact is a step at this rate: the presses are fast",
    ("off_after_onset_s", "upper"): "the heater's power changes late (1.5 s or more after the onset): a slow "
    "response, not a switch at the press (the scene puts heater = 'step' there)",
    ("off_after_onset_s", "lower"): "the heater's power changes before the onset",
    ("heat_capacity_ratio", "lower"): "the passive channel's scale is not identified (objects at its own "
    "temperature give it no signal): held at a tenth of the heated twin's",
    ("conductance_ratio", "lower"): "the passive channel's contact is not identified: held at the bound",
    ("gap_um", "upper"): "the approach passes no heat the curves show: the gap model is not asked for",
    ("gap_um", "lower"): "the gap closes to nothing: a residual gap below the contact's own resistance (k_air / H, "
    "~40 um) changes nothing the curves show, so it is not identified either; the approach speed carries the term",
    ("speed_mm_s", "upper"): "the gap closes faster than the samples resolve: the approach acts as a step at contact",
    ("speed_mm_s", "lower"): "the gap stays narrow for the whole window: the approach is a slow, flat exchange",
    ("drift_end_s", "lower"): "the contact ends the reading's drift faster than the samples resolve (a kink)",
    ("drift_end_s", "upper"): "the drift goes on through the contact: the contact does not end it",
    ("", ""): "the data push it there: the model lacks something the curves show (check the residual)",
}


def calibration_report(
    problem: CalibrationProblem,
    fit: optimize.OptimizeResult,
    res: np.ndarray,
    own_res: np.ndarray,
    values: dict[str, float],
    per_touch: list[dict[str, float]],
    noise: dict[str, dict[str, float]],
    evaluations: int,
    seconds: float,
) -> dict[str, Any]:
    """Parameters (value, bounds, at a bound, posterior s.d.), residuals in noise sigma, and the
    parameters the data do not identify."""
    params, at_bound, unidentified = _parameter_entries(problem, fit, values, per_touch)
    return {
        "model": "lumped channel(s) + two thermistor lags + contact ramp + pre-contact drift"
        + (
            " + heater switched off after the onset"
            if problem.heater_off and "heater_steps" not in problem.nuisance
            else ""
        )
        + "".join(f" + {'' if n in SHARED_TERMS else 'per touch: '}{NUISANCE_DOC[n]}" for n in problem.nuisance),
        "parameters": params,
        "at_bound": at_bound,
        "not_identified": unidentified,
        "per_touch": per_touch,
        "noise": noise,
        "residual": _residual_report(problem, res, own_res, noise, per_touch),
        "solver": {
            "evaluations": evaluations,
            "seconds": seconds,
            "status": int(fit.status),
            "cost": float(fit.cost),
            # the refinement's samples weighed by 1 / their noise s.d. (else all alike, in K)
            "noise_weighted": bool(problem.noise_weighted),
        },
    }


def _parameter_entries(
    problem: CalibrationProblem,
    fit: optimize.OptimizeResult,
    values: dict[str, float],
    per_touch: list[dict[str, float]],
) -> tuple[dict[str, Any], list[str], list[str]]:
    """Every shared parameter's entry (value, unit, bounds, meaning, posterior s.d., at a bound and
    why, identified or why not) and the fitted ambient's; the names at a bound and not identified."""
    k = len(problem.shared)
    jac = np.asarray(fit.jac.toarray() if hasattr(fit.jac, "toarray") else fit.jac)[:, :k]
    dof = max(len(fit.fun) - problem.n_free, 1)
    scale2 = float((fit.fun**2).sum()) / dof
    try:
        cov = np.linalg.pinv(jac.T @ jac) * scale2
    except np.linalg.LinAlgError:  # pragma: no cover - pinv of a finite matrix converges
        cov = np.full((k, k), np.inf)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    corr = cov / np.maximum(np.outer(sd, sd), 1e-300)
    params: dict[str, Any] = {}
    at_bound, unidentified = [], []
    for j, p in enumerate(problem.shared):
        free = float(fit.x[j])
        span = p.to_free(p.hi) - p.to_free(p.lo)
        edge = None
        if free - p.to_free(p.lo) < 1e-3 * span:
            edge = "lower"
        elif p.to_free(p.hi) - free < 1e-3 * span:
            edge = "upper"
        partner = [
            problem.shared[i].name for i in range(k) if i != j and abs(corr[j, i]) > 0.99 and np.isfinite(corr[j, i])
        ]
        loose = sd[j] > (UNIDENTIFIED_LOG_SD if p.log else 0.25)
        entry: dict[str, Any] = {
            "value": values[p.name],
            "unit": p.unit,
            "bounds": [p.lo, p.hi],
            "meaning": p.doc,
            ("sd_log" if p.log else "sd"): float(sd[j]),
        }
        if edge:
            entry["at_bound"] = edge
            entry["why_at_bound"] = _BOUND_REASONS.get((p.name.split(".")[-1], edge), _BOUND_REASONS[("", "")])
            at_bound.append(p.name)
        if loose or partner:
            entry["identified"] = False
            spread = f"a factor {math.exp(min(sd[j], 700.0)):.3g}" if p.log else f"{sd[j]:.3g}"
            entry["why_not"] = f"posterior s.d. {spread}" if loose else f"correlated > 0.99 with {', '.join(partner)}"
            unidentified.append(p.name)
        params[p.name] = entry
    if "heater.ambient_c" in values:
        params["heater.ambient_c"] = {
            "value": values["heater.ambient_c"],
            "unit": "degC",
            "bounds": [None, None],
            "meaning": "the temperature the heated channel loses heat to (its heater's power is G (T - T_amb))",
        }
        if values["heater.ambient_c"] > min(r["heated_onset_c"] for r in per_touch):
            params["heater.ambient_c"]["note"] = (
                "above the heated reading: the fitted power change is a rise (more heating after the press, "
                "as a controller that goes on holding its set point adds), not a switch-off"
            )
    return params, at_bound, unidentified


def _residual_report(
    problem: CalibrationProblem,
    res: np.ndarray,
    own_res: np.ndarray,
    noise: dict[str, dict[str, float]],
    per_touch: list[dict[str, float]],
) -> dict[str, Any]:
    """The residual with each touch's own contact and with the shared one (``res``), its kinks and
    where it is in time; fills every touch's row with its RMS per channel."""
    residual = residual_summary(problem, own_res, noise, per_touch, "own")
    residual["shared_contact"] = residual_summary(problem, res, noise, per_touch, "shared")
    # slope changes at a few instants (contact events no smooth model follows): how much they are
    residual["kinks"] = residual_kinks(
        own_res,
        problem.t,
        problem.mask,
        problem.onset,
        FIT_HZ,
        ("heated", "passive") if problem.passive else ("heated",),
    )
    # where the residual is in time (the contact's start, the first second, later)
    residual["windows"] = residual_windows(
        own_res, problem.t, problem.mask, problem.onset, ("heated", "passive") if problem.passive else ("heated",)
    )
    residual["contact"] = (
        "each touch with its own contact (conductance factor, lead, build-up: the touch's nuisance "
        "parameters, refitted with everything else shared); shared_contact: one contact for every touch"
    )
    return residual


def residual_summary(
    problem: CalibrationProblem,
    res: np.ndarray,
    noise: dict[str, dict[str, float]],
    per_touch: list[dict[str, float]],
    tag: str,
) -> dict[str, Any]:
    """Residuals ``res`` (C, n, W) per channel and overall: RMS in K and in noise sigma, two ways:

    - ``rms_sigma``: against ``sigma(t)^2 = sigma_w^2 + (sigma_t dx/dt)^2`` (white noise from a
      0.25 s spline's remainder before the onset, timing jitter; see
      :func:`~tactile_learn.calibration.thermal_touches.noise_levels`);
    - ``rms_sigma_precontact``: ``sigma_w`` replaced by the pre-contact segment's scatter about a
      quadratic trend at the recorder's rate (``precontact_k``): the correlated noise's own
      variance at every time scale up to the segment's length (~0.4 s), which the spline's knots
      would partly follow.

    Both compare a per-sample RMS with a per-sample variance: a correlated noise has the same
    variance per sample, it only gives the residual fewer independent samples. Each touch's row
    gets ``<channel>_rms_k`` (tag ``shared``) or ``<channel>_own_rms_k`` (tag ``own``)."""
    channels = ("heated", "passive") if problem.passive else ("heated",)
    out: dict[str, Any] = {}
    total_k, total_z, total_zp = [], [], []
    for c, ch in enumerate(channels):
        nz = noise.get(ch, {"white_k": 1e-3, "timing_jitter_s": 0.0})
        fitted = problem.x[c] + res[c]  # the model's curve
        jitter = nz["timing_jitter_s"] * np.gradient(fitted, axis=1) * FIT_HZ
        sigma = np.sqrt(nz["white_k"] ** 2 + jitter**2)
        sigma_pre = np.sqrt(nz.get("precontact_k", nz["white_k"]) ** 2 + jitter**2)
        r = res[c][problem.mask]
        z = (res[c] / sigma)[problem.mask]
        zp = (res[c] / sigma_pre)[problem.mask]
        total_k.append(r)
        total_z.append(z)
        total_zp.append(zp)
        out[ch] = {
            "rms_k": float(np.sqrt(np.mean(r**2))),
            "rms_sigma": float(np.sqrt(np.mean(z**2))),
            "rms_sigma_precontact": float(np.sqrt(np.mean(zp**2))),
        }
        key = f"{ch}_rms_k" if tag == "shared" else f"{ch}_own_rms_k"
        for i, row in enumerate(per_touch):
            row[key] = float(np.sqrt(np.mean(res[c, i][problem.mask[i]] ** 2)))
    rms_sigma = float(np.sqrt(np.mean(np.concatenate(total_z) ** 2)))
    return {
        **out,
        "rms_k": float(np.sqrt(np.mean(np.concatenate(total_k) ** 2))),
        "rms_sigma": rms_sigma,
        "rms_sigma_precontact": float(np.sqrt(np.mean(np.concatenate(total_zp) ** 2))),
        "within_3_sigma": rms_sigma <= 3.0,
    }


def event_report(problem: CalibrationProblem, fit: optimize.OptimizeResult) -> dict[str, Any]:
    """Every contact event: its touch, time, each channel's conductance factor with its posterior
    s.d. (log) and whether it sits at a bound; how many factors sit at a bound."""
    events = problem.events(fit.x)
    assert problem.event_t is not None
    times, factors = events if events is not None else (problem.event_t, np.ones((1, *problem.event_t.shape)))
    jac = np.asarray(fit.jac)
    cov = np.linalg.pinv(jac.T @ jac) * float(np.mean(fit.fun**2))
    names = [p.name for p in problem.per_touch]
    channels = problem.event_channels()
    bound = math.log(EVENT_FACTOR_MAX)
    rows, at_bound = [], 0
    for i in range(problem.n):
        for k in np.flatnonzero(np.isfinite(problem.event_t[i])):
            # the recording's file name only (a report goes into a model card: no path of this machine)
            row: dict[str, Any] = {"touch": Path(problem.touches[i].file).name, "t_s": float(times[i, k])}
            for c, ch in enumerate(channels):
                col = problem.n_free + names.index(f"event{k}.{ch}_log_factor") * problem.n + i
                log_f = math.log(float(factors[c, i, k]))
                row[f"{ch}_factor"] = float(factors[c, i, k])
                row[f"{ch}_sd_log"] = float(np.sqrt(max(cov[col, col], 0.0)))
                if bound - abs(log_f) < 1e-3 * 2 * bound:  # within 1e-3 of the span, as the other parameters
                    row[f"{ch}_at_bound"] = True
                    at_bound += 1
            rows.append(row)
    return {
        "events": rows,
        "count": len(rows),
        "factor_bounds": [1.0 / EVENT_FACTOR_MAX, EVENT_FACTOR_MAX],
        "factors_at_bound": at_bound,
        "why_at_bound": "a step the fit would make larger than twofold: what the residual holds there is more than a "
        "change of the contact conductance (the kinks are sharper than a step behind the thermistor's lags can bend "
        "the reading)"
        if at_bound
        else None,
        "meaning": "the contact conductance of each channel times the factor from the event's time on (slip or "
        "creep of the pad while the force holds); events found at the kinks of the own-contact residual",
    }


def touch_bounds(problem: CalibrationProblem, free: np.ndarray) -> dict[str, Any]:
    """Every touch's own contact: how many touches sit at a bound of each parameter, and why."""
    lo, hi = problem.bounds()
    k, n = problem.n_free, problem.n
    out: dict[str, Any] = {}
    for g, p in enumerate(problem.per_touch):
        if p.name.startswith("event"):  # reported with the events (contact_events)
            continue
        cols = slice(k + g * n, k + (g + 1) * n)
        span = hi[cols] - lo[cols]
        low = int(np.sum(free[cols] - lo[cols] < 1e-3 * span))
        high = int(np.sum(hi[cols] - free[cols] < 1e-3 * span))
        out[p.name] = {"bounds": [p.lo, p.hi], "meaning": p.doc, "touches_at_lower": low, "touches_at_upper": high}
        if low or high:
            out[p.name]["why_at_bound"] = (
                "a touch whose curve hardly depends on it (a wood at the sensor's own temperature barely "
                "depends on its contact) drifts to the bound; its prior keeps the rest near the shared value"
                if "conductance" in p.name
                else "the touch's curve asks for a contact further from the shared one than the bound allows: "
                "the model lacks something at the press (see the residual)"
            )
    return out
