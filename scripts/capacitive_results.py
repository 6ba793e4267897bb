"""The capacitive array's figures (docs/capacitive.md): a recipe over the package's API.

    python scripts/capacitive_results.py calibration --json results/capacitive-calibration.json
    python scripts/capacitive_results.py hysteresis --json results/capacitive-hysteresis.json
    python scripts/capacitive_results.py fingertip --method capacitive8 --json results/fingertip.json
    python scripts/capacitive_results.py tune --json results/capacitive-tune.json

- ``calibration``: fit the capacitive8 device from the rig's presses (``capacitive8_rig``, seed 7),
  compare the table with the device's true parameters, then the cell-load error on held-out presses
  (``capacitive8``, seed 3) of three front ends: the nominal design (uncalibrated), calibrated
  without hysteresis compensation, calibrated and compensated.
- ``hysteresis``: full-scale load-unload cycles (0 -> 200 g -> 0 at the tab, 41 frames) of a probe on
  cells of the device: the loop in the raw readings, and in the loads read back before and after
  compensation (widest gap between loading and unloading at the same applied load, % of full scale).
- ``fingertip``: episodes of the fingertip scene through the pipeline, skipping against running
  the thermal classifier everywhere: skipped frames and pixels, time per frame, material accuracy.
- ``tune``: the classical methods' settings swept on validation presses (seed 2): how the defaults
  were chosen.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import sys
from functools import partial
from typing import Any

import numpy as np

from synth.config import replace
from synth.dataset import simulate_shard
from synth.io import atomic_write_json, json_dumps
from synth.scene import load_scene
from synth.sensors.capacitive import CapacitiveModel, PressGenerator
from synth.sensors.capacitive.config import G_TO_N
from synth.sensors.capacitive.physics import device_cells
from synth.stimuli import KINDS
from tactile_learn.calibration.capacitive import CapacitiveFrontEnd, fit_calibration
from tactile_learn.tasks import get_task
from tactile_learn.tasks.capacitive import front_end_errors
from tactile_learn.timing import timed


def calibration(args: argparse.Namespace) -> dict[str, Any]:
    rig = load_scene("capacitive8_rig")
    presses = simulate_shard(rig, 7, 0, 192)
    (table, summary), fit_s = timed(partial(fit_calibration, presses["readings"], presses["cell_load"], rig.sensor))
    gain, stiffness = device_cells(rig.sensor)
    scene = load_scene("capacitive8")
    config = dataclasses.replace(scene.sensor, calibration=table)
    test = simulate_shard(scene, 3, 0, args.presses)
    full = config.readout.full_scale_n
    variants = {
        "uncalibrated (nominal design)": CapacitiveFrontEnd(config, calibration="nominal"),
        "calibrated, no hysteresis compensation": CapacitiveFrontEnd(config, hysteresis=False),
        "calibrated and compensated": CapacitiveFrontEnd(config),
    }
    errors = {}
    for name, front in variants.items():
        loads = front.loads(test["readings"])
        errors[name] = front_end_errors(loads, test["cell_load"], full)
        per_cell = np.median(np.abs(loads - test["cell_load"]).reshape(-1, config.n_cells), axis=0) / G_TO_N
        errors[name]["per_cell_median_g"] = {"median": float(np.median(per_cell)), "worst": float(per_cell.max())}
    return {
        "fit": {**summary, "seconds": fit_s},
        "recovered": {
            "gain_abs_err_max": float(np.abs(np.array(table.gain) - gain.ravel()).max()),
            "stiffness_abs_err_max": float(np.abs(np.array(table.stiffness) - stiffness.ravel()).max()),
            "crosstalk": [table.crosstalk, rig.sensor.readout.crosstalk],
            "hysteresis_width": [table.hysteresis_width, rig.sensor.hysteresis.width],
            "play_share": [table.play_share, rig.sensor.hysteresis.play_share],
        },
        "test": {"scene": "capacitive8", "seed": 3, "presses": args.presses, "frames": args.presses * 8},
        "cell_load_error": errors,
    }


def _loop_width(values: np.ndarray, full: float) -> float:
    """Widest gap between the unloading and the loading half of symmetric cycles ``(C, F)`` at the
    same applied load, averaged over the cycles first (the noise averages out, the loop does not),
    as a share of ``full``."""
    f = values.shape[-1]
    up, down = values[:, : f // 2 + 1], values[:, f // 2 :][:, ::-1]
    return float(np.max(np.abs((down - up).mean(axis=0))) / full)


def hysteresis(args: argparse.Namespace) -> dict[str, Any]:
    scene = load_scene("capacitive8")
    frames = 41
    out: dict[str, Any] = {}
    for noise in (False, True):
        config = replace(scene.sensor, "readout.drift_v", 0.0)
        config = replace(config, "readout.drift_v_per_frame", 0.0)
        model = CapacitiveModel(config, frames=frames)
        gen = PressGenerator(config, model)
        rng = np.random.default_rng(11)
        n = args.cycles
        contacts = gen.draw_contacts(n, rng)
        cells = rng.integers(0, 64, size=n)
        contacts.update(
            count=np.ones(n, int),
            present=np.ones((n, 1), bool),
            kind=np.full((n, 1), KINDS.index("punch")),  # the rig's round probe
            x_mm=((cells % 8 + 0.5) * 1.8)[:, None],
            y_mm=((cells // 8 + 0.5) * 1.8)[:, None],
            radius_mm=np.full((n, 1), 0.7),
        )
        contacts = {k: v[:, :1] if v.ndim == 2 else v for k, v in contacts.items()}
        share = np.sin(np.pi * np.linspace(0, 1, frames))
        share[-1] = 0.0
        # the probe's force for 200 g on the tab below: the cover passes ~90 % of it
        contacts["force_n"] = np.full((n, 1), config.readout.full_scale_n / 0.9)
        stim = gen.press(contacts, share[None, :, None] * np.ones((n, 1, 1)), np.zeros((n, frames)))
        truth = model.physics(stim)
        idx = (np.arange(n), slice(None), cells // 8, cells % 8)
        readings = model.forward(stim, rng if noise else None)
        calibrated = scene.sensor.calibration
        assert calibrated is not None
        before = CapacitiveFrontEnd(config, calibration=calibrated, hysteresis=False, drift=False).loads(readings)
        after = CapacitiveFrontEnd(config, calibration=calibrated, drift=False).loads(readings)
        full = config.readout.full_scale_n
        raw = readings[idx]
        out["noisy" if noise else "noise-free"] = {
            "cycles": n,
            "peak_load_g": float(truth[idx].max(axis=1).mean() / G_TO_N),
            "readings_loop_pct_of_response": 100 * _loop_width(raw, float((raw.max(axis=1) - raw[:, 0]).mean())),
            "loads_loop_pct_before_compensation": 100 * _loop_width(before[idx], full),
            "loads_loop_pct_after_compensation": 100 * _loop_width(after[idx], full),
            "loop_closes_g": float(np.abs(after[idx][:, -1]).mean() / G_TO_N),
        }
    return out


def fingertip(args: argparse.Namespace) -> dict[str, Any]:
    from tactile_learn.fingertip import FingertipPipeline

    scene = load_scene("fingertip")
    data = simulate_shard(scene, 31, 0, args.episodes)
    result: dict[str, Any] = {"episodes": args.episodes, "seed": 31, "capacitive_method": args.method}
    outputs = {}
    for skip in (True, False):
        pipe = FingertipPipeline(scene, capacitive_method=args.method, skip=skip).fit()
        pipe.run(data["readings"][0], data["thermal_readings"][0])  # warm-up
        frames = [pipe.run(data["readings"][e], data["thermal_readings"][e]) for e in range(args.episodes)]
        seconds = np.array([f.seconds for ep in frames for f in ep])
        classified = np.array([f.classified for ep in frames for f in ep])
        materials = np.array([f.thermistor_material for ep in frames for f in ep])
        touching = np.array([f.touching for ep in frames for f in ep])
        outputs[skip] = (materials, classified, touching)
        key = "skip" if skip else "everything"
        result[key] = {
            "ms_per_frame_median": float(np.median(seconds) * 1e3),
            "ms_per_frame_mean": float(seconds.mean() * 1e3),
            "ms_per_frame_p95": float(np.percentile(seconds, 95) * 1e3),
            "frames_with_thermal_run": float(classified.any(axis=1).mean()),
            "thermistor_frames_classified": float(classified.mean()),
        }
    materials, classified, touching = outputs[True]
    truth_contact = data["thermistor_contact"].reshape(-1, 16)
    truth_material = np.repeat(data["thermistor_material"], scene.sensor.frames, axis=0)
    named = classified & (materials >= 0)
    right = named & truth_contact & (materials == truth_material)
    times = np.tile(scene.sensor.frame_times_s, args.episodes)[:, None]
    onset = np.repeat(data["latent_onset_s"].min(axis=1), scene.sensor.frames)[:, None]
    late = truth_contact & (times >= onset + 1.0)
    result["skipped_frames"] = 1.0 - result["skip"]["frames_with_thermal_run"]
    result["skipped_thermistor_frames"] = 1.0 - result["skip"]["thermistor_frames_classified"]
    result["time_ratio_median"] = result["skip"]["ms_per_frame_median"] / result["everything"]["ms_per_frame_median"]
    result["time_ratio_mean"] = result["skip"]["ms_per_frame_mean"] / result["everything"]["ms_per_frame_mean"]
    result["same_materials_on_contact"] = bool(
        np.array_equal(np.where(classified, materials, -1), np.where(classified, outputs[False][0], -1))
    )
    result["thermistor_contact"] = {  # the pressure image's "under contact" against the truth
        "precision": float((touching & truth_contact).sum() / max(touching.sum(), 1)),
        "recall": float((touching & truth_contact).sum() / max(truth_contact.sum(), 1)),
    }
    result["material_accuracy"] = {
        "classified_contact_thermistors": float(right.sum() / max((named & truth_contact).sum(), 1)),
        "after_1s_of_contact": float((right & late).sum() / max((named & late).sum(), 1)),
        "recognised_after_1s": float((named & late).sum() / max(late.sum(), 1)),
    }
    return result


def tune(args: argparse.Namespace) -> dict[str, Any]:
    from tactile_learn.estimators.classical.capacitive import BicubicEstimator, DeconvolutionEstimator

    task = get_task("capacitive")
    scene = load_scene("capacitive8")
    data = task.eval_data(simulate_shard(scene, 2, 0, 250), scene)  # type: ignore[attr-defined]
    rows = []
    grids: dict[str, tuple[Any, dict[str, list[Any]]]] = {
        "bicubic": (BicubicEstimator, {"threshold": [0.3, 0.35, 0.4, 0.45], "reach": [0, 8], "floor_sigmas": [4.0]}),
        "deconvolution": (
            DeconvolutionEstimator,
            {
                "smoothness": [100.0, 300.0, 1000.0],
                "threshold": [0.2, 0.25, 0.3],
                "reach": [0, 8],
                "floor_sigmas": [4.0, 32.0],
            },
        ),
    }
    for name, (cls, grid) in grids.items():
        for values in itertools.product(*grid.values()):
            params = dict(zip(grid, values, strict=True))
            m = task.metrics(cls(data.scene, **params).fit().predict(data.inputs), data)
            rows.append(
                {
                    "method": name,
                    **params,
                    **{
                        k: m[k]
                        for k in (
                            "iou_mean",
                            "separation_rate",
                            "centroid_err_mm_median",
                            "orientation_err_deg_median",
                            "missed_rate",
                            "false_contact_rate",
                        )
                    },
                }
            )
            print(rows[-1], file=sys.stderr, flush=True)
    return {"validation": {"scene": "capacitive8", "seed": 2, "presses": 250}, "grid": rows}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("what", choices=("calibration", "hysteresis", "fingertip", "tune"))
    parser.add_argument("--json", default=None)
    parser.add_argument("--presses", type=int, default=1000, help="held-out presses (calibration)")
    parser.add_argument("--cycles", type=int, default=200, help="load-unload cycles (hysteresis)")
    parser.add_argument("--episodes", type=int, default=200, help="fingertip episodes")
    parser.add_argument("--method", default="deconvolution", help="capacitive method of the fingertip")
    args = parser.parse_args()
    result = {"calibration": calibration, "hysteresis": hysteresis, "fingertip": fingertip, "tune": tune}[args.what](
        args
    )
    print(json_dumps(result))
    if args.json:
        atomic_write_json(args.json, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
