"""Does a contact conductance that follows the force explain the calibration's residual? And is
the recorder's noise white? (issue 11's calibration floor: residual <= 3 noise sigma.)

    python scripts/thermal_force_contact.py --label R_1 --json results/thermal_force_contact.json

1. The labelled session's touches are fitted twice with the calibration's model and multi-start
   solver (``tactile_learn.calibration.thermal_problem``): as calibrated (a contact that builds up over a
   ramp, then holds), and with a contact that follows the recorded force: the build-up is the sum
   of step contacts weighted by the increments of ``w(t) = (F(t + shift) / F_plateau)^k`` (from the
   first touch; ``k`` and ``shift`` fitted, the ramp dropped), so the conductance rises and falls
   with the force all through the press. Each step is the model's closed form, so the force term
   is the convolution of the force's increments with the closed-form step response (exact for a
   force held constant over each 10 ms sample). Both fits report their RMS residual per channel.
2. The pre-contact segment of every touch (the white noise's source): its residual from a
   quadratic trend, that residual's autocorrelation at lags of 1, 2, 5, 10 and 20 samples (white
   noise: ~0 at every lag), and its RMS beside the calibration's white-noise estimate.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from scipy import optimize

sys.path.insert(0, str(Path(__file__).resolve().parent))
from thermal_robot_protocol import robot_data, split

from synth.io import atomic_write_json, json_dumps
from synth.materials import get_material
from synth.sensors.thermal.dynamics import channel_terms
from tactile_learn.calibration.thermal_parameters import Parameter
from tactile_learn.calibration.thermal_problem import CalibrationProblem
from tactile_learn.calibration.thermal_touches import FIT_HZ, noise_levels, prepare_touches
from tactile_learn.thermal_adapt import _classes, _onset
from tactile_learn.thermal_recordings import Touch, press_profile, read_recordings
from tactile_learn.timing import timed

#: the force term's time step: the fitting grid divided by this
SUB = 5


class ForceContact(CalibrationProblem):
    """The calibration's problem with the contact's build-up read from the force (see the module)."""

    def __init__(self, touches: list[Any], classes: list[Any], forces: list[tuple[np.ndarray, np.ndarray]]) -> None:
        super().__init__(touches, classes, True)
        self.forces = forces
        P = Parameter
        # the ramp is replaced by the force: pinned at its lower bound (the design ignores it)
        ramp = P("contact.ramp_s", "s", 0.02, 0.0201, 0.02, True, "unused: the force times the build-up")
        self.shared = [ramp if p.name == "contact.ramp_s" else p for p in self.shared]
        self.shared.append(P("contact.force_exponent", "", 0.0, 4.0, 1.0, False, "G ~ (F / F_plateau)^k"))
        self.shared.append(P("contact.force_shift_s", "s", -0.5, 1.0, 0.1, False, "thermal contact leads the force"))

    def design(self, free: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        cols, power, extra = super().design(free)  # extra: the opt-in per-touch columns, passed on
        values, _, _ = self.unpack(free)
        k, shift = values["contact.force_exponent"], values["contact.force_shift_s"]
        e, alpha = self.class_e[self.label], self.class_alpha[self.label]
        spreading = 4.0 * e * np.sqrt(alpha) / (math.pi * values["contact.radius_mm"] * 1e-3)
        n_fine = self.length * SUB
        tau = np.arange(n_fine) / (FIT_HZ * SUB)
        weight = np.zeros((self.n, n_fine))
        for i, tc in enumerate(self.touches):
            press = np.interp(tc.t[0] + tau + shift, *self.forces[i])
            weight[i] = np.where(press > 0.05, np.clip(press, 0.0, None) ** k, 0.0)
        steps = np.diff(weight, axis=1, prepend=0.0)
        for c, ch in enumerate(("heated", "passive") if self.passive else ("heated",)):
            model = self.channel_model(values, ch, e, spreading)
            step = channel_terms(model, np.broadcast_to(tau, (self.n, n_fine))).obj
            obj = np.stack([np.convolve(steps[i], step[i])[:n_fine] for i in range(self.n)])[:, ::SUB]
            # the design's obj enters its columns as 1 + obj, drift + lead_lag obj and -obj
            old = -cols[c, :, :, 2]
            lead_lag = values[f"{ch}.lag_s"] + values[f"{ch}.lag2_s"]
            cols[c, :, :, 0] += obj - old
            cols[c, :, :, 1] += lead_lag * (obj - old)
            cols[c, :, :, 2] = -obj
        return cols, power, extra


def fit(problem: CalibrationProblem, starts: int = 6, seed: int = 0) -> dict[str, Any]:
    """The calibration's multi-start (short runs from jittered starts, the best to convergence)."""
    lo, hi = problem.bounds()
    rng = np.random.default_rng(seed)

    def run(x0: np.ndarray, nfev: int) -> optimize.OptimizeResult:
        x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
        return optimize.least_squares(
            problem.residuals, x0, bounds=(lo, hi), x_scale="jac", max_nfev=nfev, diff_step=1e-5
        )

    base = problem.start()
    runs = [
        run(base + (rng.normal(0.0, 1.0, len(base)) * np.minimum(1.0, 0.25 * (hi - lo)) if s else 0.0), 15)
        for s in range(starts)
    ]
    final = run(min(runs, key=lambda f: f.cost).x, 200)
    res, _, _ = problem.solve(final.x)
    rms = {ch: float(np.sqrt(np.mean(res[c][problem.mask] ** 2))) for c, ch in enumerate(("heated", "passive"))}
    shared = {p.name: p.from_free(float(v)) for p, v in zip(problem.shared, final.x, strict=True)}
    return {"rms_mk": {k: v * 1e3 for k, v in rms.items()}, "parameters": shared}


def whiteness(touches: list[Touch]) -> dict[str, Any]:
    """The pre-contact segments' residual from a quadratic trend and its autocorrelation."""
    out: dict[str, Any] = {}
    for name, column in (("heated", "temperature_c"), ("passive", "passive_c")):
        rms, acf = [], []
        for t in touches:
            onset, _ = _onset(t)
            keep = (t.time_s > t.time_s[0] + 0.05) & (t.time_s < onset - 0.35)
            x, tt = t.channel(column)[keep], t.time_s[keep]
            rest = x - np.polyval(np.polyfit(tt, x, 2), tt)
            rms.append(float(np.sqrt(np.mean(rest**2))))
            acf.append([float(np.corrcoef(rest[:-k], rest[k:])[0, 1]) for k in (1, 2, 5, 10, 20)])
        out[name] = {
            "quadratic_trend_rms_mk": float(np.median(rms)) * 1e3,
            "autocorrelation_lags": [1, 2, 5, 10, 20],
            "autocorrelation_median": np.median(np.array(acf), axis=0).tolist(),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default=None, help="the thermal-robot folder")
    parser.add_argument("--label", default="R_1", help="the labelled session")
    parser.add_argument("--json", default=None, help="write the results here")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        labelled, _ = split(robot_data(args.data), args.label, Path(tmp))
        touches = [t for t in read_recordings(labelled) if t.material]
        classes = _classes(touches, None)
        names = [c[0] for c in classes]
    series, noise_h, noise_p, forces = [], [], [], []
    for t in touches:
        onset, _ = _onset(t)
        series.append((t.file, names.index(str(t.material)), t.time_s, t.temperature_c, t.passive_c, onset))
        noise_h.append((t.time_s, t.temperature_c, onset))
        noise_p.append((t.time_s, t.channel("passive_c"), onset))
        profile = press_profile(t.time_s, t.channel("force"))
        if profile is None:
            raise SystemExit(f"{t.file}: no press in its force column")
        forces.append((t.time_s, profile))
    fit_touches = prepare_touches(series)
    materials = [[get_material(m) for m in mats] for _, mats in classes]
    result: dict[str, Any] = {"labelled": args.label}
    result["noise"] = {
        "calibration_estimate": {
            "heated": noise_levels(noise_h),
            "passive": noise_levels(noise_p),
        },
        "pre_contact": whiteness(touches),
    }
    for name, problem in (
        ("ramp_contact", CalibrationProblem(fit_touches, materials, True)),
        ("force_contact", ForceContact(fit_touches, materials, forces)),
    ):
        result[name], seconds = timed(partial(fit, problem))
        result[name]["seconds"] = seconds
        print(name, json.dumps(result[name]["rms_mk"]), flush=True)
    if args.json:
        atomic_write_json(args.json, result)
    print(json_dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
