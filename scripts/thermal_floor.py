"""How low can any calibration of the robot recordings go? The floor analysis of issue 11's residual.

    python scripts/thermal_floor.py --json results/thermal_robot_residual_floor.json

Three figures per channel and condition (M metal, W wood, CW cooled wood), every session:

- ``per_touch``: every touch fitted ALONE with every physical parameter of the calibration's model
  free (both channels' heat capacity, loss, contact, lags, the radius, the contact's lead and
  build-up, the heater's power change; the linear terms as in the calibration). No shared
  calibration of the same model can leave less on a touch than its own fit: the model family's floor.
  Multi-start: the default start, the labelled session's calibrated values (``--start-from``, a
  calibration report's parameters; R_1's by default), and jittered starts around both.
- ``repeat``: the touches of one session and condition (3 each) aligned at their detected onsets
  and levelled at the onset: the RMS of each touch's difference from the others' mean, per time
  window after the onset, raw and after the best per-touch affine map (time shift and scale,
  amplitude gain and offset). What is left after the map is touch-to-touch variation that a
  deterministic model with per-session parameters can follow only through a per-touch cause.
- ``noise``: the noise scale by scale, from the records' quiet parts (the pre-contact segments of
  every touch; the passive channel on wood and metal at room temperature 1-6 s after the onset, where
  nothing flows but the object's small offset): what a cubic spline with knots every 0.125..4 s
  leaves (see :func:`quiet_noise`), against the white sigma the report divides by.

The data: ``--data``, else ``$TACTILE_THERMAL_ROBOT``, else ``../shared/data/thermal-robot``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy import optimize

from synth.io import atomic_write_json
from synth.materials import get_material
from tactile_learn.calibration import thermal_calibration as tcal
from tactile_learn.calibration.thermal_problem import CalibrationProblem
from tactile_learn.calibration.thermal_report import residual_summary
from tactile_learn.calibration.thermal_scene import _classes, _onset
from tactile_learn.calibration.thermal_touches import QUIET_BEFORE_S
from tactile_learn.thermal_recordings import Touch, read_recordings

sys.path.insert(0, str(Path(__file__).resolve().parent))
from thermal_robot_protocol import robot_data  # a sibling script

#: time windows after the onset (s) the figures are given in (None: open)
WINDOWS: tuple[tuple[float | None, float | None], ...] = (
    (None, 0.0),
    (0.0, 0.5),
    (0.5, 1.0),
    (1.0, 2.0),
    (2.0, 4.0),
    (4.0, None),
)


def session_touches(data: Path, session: str) -> tuple[list[Touch], list[tcal.FitTouch], list[Any], dict[str, Any]]:
    """One session's touches, their fitting-grid records, the class materials and the session's noise
    (as ``calibrate_recordings`` computes them)."""
    touches = [t for t in read_recordings(data) if t.info.get("session") == session and t.material]
    classes = _classes(touches, None)
    names = [c[0] for c in classes]
    series, heated_noise, passive_noise = [], [], []
    for t in touches:
        onset, _ = _onset(t)
        series.append((t.file, names.index(str(t.material)), t.time_s, t.temperature_c, t.passive_c, onset))
        heated_noise.append((t.time_s, t.temperature_c, onset))
        passive_noise.append((t.time_s, t.passive_c, onset))
    noise = {"heated": tcal.noise_levels(heated_noise), "passive": tcal.noise_levels(passive_noise)}
    materials = [[get_material(m) for m in mats] for _, mats in classes]
    return touches, tcal.prepare_touches(series), materials, noise


def per_touch_fit(
    touch: tcal.FitTouch,
    materials: list[Any],
    noise: dict[str, Any],
    start_values: list[dict[str, float]],
    starts: int,
    seed: int,
    weighted: bool = False,
) -> tuple[np.ndarray, dict[str, Any], dict[str, float]]:
    """One touch fitted alone, every nonlinear parameter free: residuals (C, W), the residual summary
    (mK and sigma per channel) and the fitted values. Starts: the default, each of ``start_values``
    (parameter values by name), then jittered around them in turn. ``weighted``: every sample in units
    of its noise s.d. (the maximum-likelihood fit in the report's unit), else all alike in K."""
    problem = CalibrationProblem([touch], materials, heater_off=True, noise=noise if weighted else None)
    lo, hi = problem.bounds()
    rng = np.random.default_rng(seed)
    bases = [problem.start()]
    for values in start_values:
        bases.append(np.array([p.to_free(min(max(values.get(p.name, p.start), p.lo), p.hi)) for p in problem.shared]))

    run = problem.fit_from

    candidates = []
    for s in range(starts):
        base = bases[s % len(bases)]
        x0 = base if s < len(bases) else base + rng.normal(0.0, 0.5, len(base)) * np.minimum(1.0, 0.25 * (hi - lo))
        candidates.append(run(x0, tcal.SHORT_RUN * 2))
    best = min(candidates, key=lambda f: f.cost)
    final = run(best.x, 300)
    res, _, _ = problem.solve(final.x)
    values, _, _ = problem.unpack(final.x)
    summary = residual_summary(problem, res, noise, [{}], "own")
    return res[:, 0], summary, values


def reading(touch: Touch, channel: str) -> np.ndarray:
    """A touch's ``heated`` or ``passive`` samples (degC)."""
    return touch.channel("temperature_c" if channel == "heated" else "passive_c")


def window_masks(t_rel: np.ndarray) -> list[np.ndarray]:
    return [(t_rel >= (-np.inf if a is None else a)) & (t_rel < (np.inf if b is None else b)) for a, b in WINDOWS]


def window_name(a: float | None, b: float | None) -> str:
    return f"[{'-' if a is None else a}, {'-' if b is None else b})"


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


# ---------------------------------------------------------------- repeatability


#: the common grid of the repeatability figures (s after the onset) and its rate
REPEAT_FROM_S, REPEAT_TO_S, REPEAT_HZ = -0.3, 6.4, 50.0


def repeatability(touches: list[Touch], onsets: list[float], channel: str) -> dict[str, Any]:
    """Touches of one session and condition on a common grid after their onsets, levelled at the
    onset: every touch's difference from the mean of the OTHER touches (leave-one-out, so a touch is
    not compared with itself), RMS per window, raw and after the best affine map of each touch
    onto the others' mean."""
    t = np.arange(REPEAT_FROM_S, REPEAT_TO_S, 1.0 / REPEAT_HZ)
    curves = []
    for touch, onset in zip(touches, onsets, strict=True):
        x = reading(touch, channel)
        c = np.interp(onset + t, touch.time_s, x)
        curves.append(c - np.interp(onset, touch.time_s, x))
    curves_a = np.array(curves)
    raw, mapped = [], []
    for i in range(len(curves_a)):
        others = np.delete(curves_a, i, axis=0).mean(axis=0)
        raw.append(curves_a[i] - others)
        # the others' mean mapped onto this touch: what a per-touch time/amplitude change can explain
        aligned = _align_mean(t, curves_a[i], np.delete(np.arange(len(curves_a)), i), touches, onsets, channel)
        mapped.append(curves_a[i] - aligned)
    masks = window_masks(t)
    # n touches, leave-one-out differences: Var(x_i - mean of the others) = s^2 (1 + 1 / (n - 1)) for
    # independent touch deviations of s.d. s; the figures are per touch (divided by that factor)
    k = math.sqrt(1.0 + 1.0 / max(len(curves_a) - 1, 1))
    return {
        "raw": [rms(np.array(raw)[:, m]) / k for m in masks],
        "affine": [rms(np.array(mapped)[:, m]) / k for m in masks],
        "all_raw": rms(np.array(raw)) / k,
        "all_affine": rms(np.array(mapped)) / k,
    }


def _align_mean(
    t: np.ndarray, target: np.ndarray, others: np.ndarray, touches: list[Touch], onsets: list[float], channel: str
) -> np.ndarray:
    """The others' mean curve, each of them mapped by one common affine time map and amplitude map
    onto ``target`` (the best fit of the others' shape to this touch)."""

    def mean_curve(theta: np.ndarray) -> np.ndarray:
        cs = []
        for j in others:
            x = reading(touches[j], channel)
            level = np.interp(onsets[j], touches[j].time_s, x)
            cs.append(np.interp(onsets[j] + theta[0] + theta[1] * t, touches[j].time_s, x) - level)
        return np.mean(cs, axis=0)

    def fitted(theta: np.ndarray) -> np.ndarray:
        c = mean_curve(theta)
        design = np.stack([np.ones_like(c), c], axis=1)
        coef, *_ = np.linalg.lstsq(design, target, rcond=None)
        return design @ coef

    fit = optimize.least_squares(
        lambda th: fitted(th) - target, np.array([0.0, 1.0]), bounds=([-0.4, 0.8], [0.4, 1.25]), diff_step=1e-4
    )
    return fitted(fit.x)


# ---------------------------------------------------------------- noise at slow time scales


def smooth_fit_rms(x: np.ndarray, t: np.ndarray, knots_s: float) -> float:
    """RMS of what a cubic spline with knots every ``knots_s`` leaves of a segment: the part of the
    noise no smooth curve of that flexibility follows."""
    from scipy.interpolate import LSQUnivariateSpline

    knots = np.arange(t[0] + knots_s, t[-1] - knots_s / 2, knots_s)
    if len(knots) == 0:
        coef = np.polyfit(t - t.mean(), x, 3)
        return rms(x - np.polyval(coef, t - t.mean()))
    return rms(x - LSQUnivariateSpline(t, x, knots, k=3)(t))


#: knot spacings (s) of the smoothing splines whose remainders measure the noise scale by scale
KNOTS_S = (0.125, 0.25, 0.5, 1.0, 2.0, 4.0)


def quiet_noise(touches: list[Touch], onsets: list[float], conditions: list[str]) -> dict[str, Any]:
    """The noise scale by scale: the median RMS that a cubic spline with knots every ``k`` s
    (KNOTS_S) leaves of the quiet parts of the records. A spline with knots every ``k`` follows every
    change slower than ~``k``, so the remainder holds the noise (and any physics) faster than that;
    its growth with ``k`` is the noise's power at slow scales (a wavelet-like ladder, which unlike a
    periodogram of these short, curved segments does not leak their trend into the low bins).
    Sources: the pre-contact segments (record start + 0.05 s to 0.5 s before the onset, both
    channels, ~0.7 s: ``k`` above that is the smoothest curve the segment holds); the passive channel
    on wood and metal 1-6 s after the onset (no heat flows there but the object's small offset);
    the heated channel on wood 1-6 s (a smooth 0.4 K curve: an upper bound at long ``k``)."""
    sources: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    for touch, onset, cond in zip(touches, onsets, conditions, strict=True):
        t = touch.time_s
        pre = (t > t[0] + 0.05) & (t < onset - QUIET_BEFORE_S)
        during = (t > onset + 1.0) & (t < onset + 6.0)
        for channel in ("heated", "passive"):
            if pre.sum() >= 60:
                sources.setdefault(f"{channel}_precontact", []).append((t[pre], reading(touch, channel)[pre]))
        if cond in ("W", "M"):
            sources.setdefault(f"passive_on_{cond}_1_to_6_s", []).append((t[during], reading(touch, "passive")[during]))
        if cond == "W":
            sources.setdefault("heated_on_W_1_to_6_s", []).append((t[during], reading(touch, "heated")[during]))
    out: dict[str, Any] = {"knots_s": list(KNOTS_S)}
    for name, segs in sources.items():
        out[name] = {
            "segments": len(segs),
            "length_s_median": float(np.median([tt[-1] - tt[0] for tt, _ in segs])),
            "rms_left_k_median": [float(np.median([smooth_fit_rms(x, tt, k) for tt, x in segs])) for k in KNOTS_S],
        }
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=None)
    parser.add_argument("--sessions", default="R_1,R_2,R_3,R_4,R_5,R_6,R_7,R_8,R_9,R_10")
    parser.add_argument("--start-from", default="results/thermal_robot_residual_events.json")
    parser.add_argument("--starts", type=int, default=6)
    parser.add_argument("--weighted", action="store_true", help="per-touch fits in noise units")
    parser.add_argument("--skip-fits", action="store_true", help="repeatability and noise only")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    data = robot_data(args.data)
    start_values: dict[str, float] = {}
    own_contacts: dict[str, dict[str, float]] = {}
    if args.start_from and Path(args.start_from).exists():
        reference = json.loads(Path(args.start_from).read_text())["none"]
        start_values = reference["parameters"]
        # the calibrated session's touches also start from their own contact of the joint refinement
        # (so their floor is at most the calibration's own-contact residual)
        own_contacts = {row["file"]: row for row in reference["touches"]}
    out: dict[str, Any] = {
        "command": " ".join(["python", "scripts/thermal_floor.py", *(argv or sys.argv[1:])]),
        "windows": [window_name(a, b) for a, b in WINDOWS],
        "weighted": bool(args.weighted),
        "per_touch": [],
        "repeat": {},
    }
    all_touches, all_onsets, all_conds = [], [], []
    for session in args.sessions.split(","):
        touches, fit_touches, materials, noise = session_touches(data, session)
        conds = [str(t.info.get("condition")) for t in touches]
        onsets = [ft.onset_s for ft in fit_touches]
        all_touches += touches
        all_onsets += onsets
        all_conds += conds
        for cond in sorted(set(conds)):
            idx = [i for i, c in enumerate(conds) if c == cond]
            for channel in ("heated", "passive"):
                out["repeat"].setdefault(f"{channel}_{cond}", []).append(
                    repeatability([touches[i] for i in idx], [onsets[i] for i in idx], channel)
                )
        if args.skip_fits:
            continue
        for i, ft in enumerate(fit_touches):
            started = time.perf_counter()
            starts_from = [start_values] if start_values else []
            own = own_contacts.get(Path(ft.file).name)
            if own and start_values:
                starts_from.append(
                    {
                        **start_values,
                        "heated.conductance_w_m2k": start_values["heated.conductance_w_m2k"]
                        * own["touch_conductance_factor"],
                        "contact.lead_s": own["touch_lead_s"],
                        "contact.ramp_s": own["touch_ramp_s"],
                    }
                )
            res, summary, values = per_touch_fit(
                ft, materials, noise, starts_from, args.starts, seed=i, weighted=args.weighted
            )
            t_rel = ft.t - ft.onset_s
            row = {
                "file": Path(ft.file).name,
                "session": session,
                "condition": conds[i],
                "seconds": time.perf_counter() - started,
                "values": {k: float(v) for k, v in values.items()},
            }
            for c, channel in enumerate(("heated", "passive")):
                row[f"{channel}_rms_k"] = summary[channel]["rms_k"]
                row[f"{channel}_rms_sigma"] = summary[channel]["rms_sigma"]
                row[f"{channel}_windows_k"] = [rms(res[c][: len(t_rel)][m]) for m in window_masks(t_rel)]
            row["rms_sigma"] = summary["rms_sigma"]
            out["per_touch"].append(row)
            print(
                f"{row['file']}: heated {1e3 * row['heated_rms_k']:.2f} mK ({row['heated_rms_sigma']:.1f} s), "
                f"passive {1e3 * row['passive_rms_k']:.2f} mK ({row['passive_rms_sigma']:.1f} s), "
                f"{row['seconds']:.0f} s",
                flush=True,
            )
    out["noise"] = quiet_noise(all_touches, all_onsets, all_conds)
    out["summary"] = summarize(out)
    print(json.dumps(out["summary"], indent=1))
    if args.json:
        atomic_write_json(args.json, out)
    return 0


def summarize(out: dict[str, Any]) -> dict[str, Any]:
    """Per channel and condition: the per-touch floor (RMS over touches, mK and sigma), the
    repeatability (raw and affine, RMS over sessions), per window."""
    summary: dict[str, Any] = {}
    for key, rows in out["repeat"].items():
        entry = {
            "repeat_raw_mk": 1e3 * rms(np.array([r["all_raw"] for r in rows])),
            "repeat_affine_mk": 1e3 * rms(np.array([r["all_affine"] for r in rows])),
            "repeat_raw_windows_mk": list(1e3 * np.sqrt(np.nanmean(np.array([r["raw"] for r in rows]) ** 2, axis=0))),
            "repeat_affine_windows_mk": list(
                1e3 * np.sqrt(np.nanmean(np.array([r["affine"] for r in rows]) ** 2, axis=0))
            ),
        }
        channel, cond = key.split("_")
        rows_t = [r for r in out["per_touch"] if r["condition"] == cond]
        if rows_t:
            entry["per_touch_mk"] = 1e3 * rms(np.array([r[f"{channel}_rms_k"] for r in rows_t]))
            entry["per_touch_sigma"] = rms(np.array([r[f"{channel}_rms_sigma"] for r in rows_t]))
            entry["per_touch_windows_mk"] = list(
                1e3 * np.sqrt(np.nanmean(np.array([r[f"{channel}_windows_k"] for r in rows_t]) ** 2, axis=0))
            )
            r1 = [r for r in rows_t if r["session"] == "R_1"]
            if r1:
                entry["per_touch_R_1_mk"] = 1e3 * rms(np.array([r[f"{channel}_rms_k"] for r in r1]))
                entry["per_touch_R_1_sigma"] = rms(np.array([r[f"{channel}_rms_sigma"] for r in r1]))
        summary[key] = entry
    return summary


if __name__ == "__main__":
    sys.exit(main())
