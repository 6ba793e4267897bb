"""Round trip of the thermal fingertip's real-sensor path, on simulated recordings.

1. A "user's sensor" that the calibrator does not know: another heat capacity, loss, heater,
   contact conductance range, sampling rate and noise than the shipped scene.
2. Its touches (one thermistor each, onset somewhere in a long record, time not starting at 0) are
   written in the recording format (touches.csv + one time_s,temperature_c CSV per touch).
3. ``ThermalTask.calibrate`` fits the sensor from a few labelled touches per material and writes a
   scene TOML.
4. The remaining touches are classified by the classical methods with the shipped scene
   (uncalibrated) and with the calibrated scene; accuracy by contact duration is printed as JSON.

    python scripts/thermal_roundtrip.py --out results/roundtrip [--per-material 2] [--n 150]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from synth.config import replace
from synth.scene import load_scene
from synth.sensors.thermal import make_simulator
from tactile_learn.tasks.thermal import ThermalTask
from tactile_learn.thermal_recordings import Touch, write_recordings

USER_SENSOR = {
    "grid": [1, 1],
    "sensor.heat_capacity_j_m2k": [1480.0, 1520.0],
    "sensor.loss_w_m2k": [175.0, 185.0],
    "sensor.heater_w_m2": [3380.0, 3420.0],
    "contact.conductance_w_m2k": [5000.0, 30000.0],
    "readout.sampling_hz": 40.0,
    "readout.noise_k": 0.015,
    "readout.duration_s": 8.0,
    "contact.onset_s": [2.5, 4.0],
    "contact.contact_s": [3.0, 3.5],
}


def simulate_user(scene_name: str, n: int, seed: int) -> tuple[list[Touch], dict[str, float]]:
    scene = load_scene(scene_name)
    config = scene.sensor
    for key, value in USER_SENSOR.items():
        config = replace(config, key, value)
    user = dataclasses.replace(scene, sensor=config, name="user_sensor")
    arrays = make_simulator(user).simulate(n, np.random.default_rng(seed))
    fs = config.readout.sampling_hz
    names = [m.name for m in config.material_list]
    touches = []
    rng = np.random.default_rng(seed + 1)
    for i in range(n):
        t0 = float(rng.uniform(0.0, 100.0))  # the logger's clock does not start at the record
        time = t0 + np.arange(arrays["readings"].shape[-1]) / fs
        touches.append(
            Touch(
                file=f"touch-{i:04d}.csv",
                time_s=time,
                temperature_c=arrays["readings"][i, 0].astype(np.float64),
                material=names[int(arrays["latent_material"][i, 0])],
                info={"release_s": f"{t0 + float(arrays['latent_release_s'][i, 0]):.4f}"},
            )
        )
    truth = {
        k: float(np.mean(v))
        for k, v in (
            ("heat_capacity_j_m2k", arrays["latent_heat_capacity_j_m2k"]),
            ("loss_w_m2k", arrays["latent_loss_w_m2k"]),
        )
    }
    return touches, truth


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True)
    parser.add_argument("--scene", default="thermal_wns")
    parser.add_argument("--n", type=int, default=150)
    parser.add_argument("--per-material", type=int, default=2)
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args()
    out = Path(args.out)
    touches, truth = simulate_user(args.scene, args.n, args.seed)
    calib, rest = [], []
    seen: dict[str, int] = {}
    for t in touches:
        assert t.material is not None
        if seen.get(t.material, 0) < args.per_material:
            seen[t.material] = seen.get(t.material, 0) + 1
            calib.append(t)
        else:
            rest.append(t)
    write_recordings(out / "calibration", calib)
    write_recordings(out / "test", [dataclasses.replace(t, info={}) for t in rest])
    task = ThermalTask()
    shipped = load_scene(args.scene)
    summary = task.calibrate(out / "calibration", out / "sensor.toml", shipped)
    calibrated = load_scene(out / "sensor.toml")
    result: dict[str, object] = {
        "true_sensor": truth,
        "calibration": summary,
        "n_calibration": len(calib),
        "n_test": len(rest),
    }
    for label, scene in (("shipped_scene", shipped), ("calibrated_scene", calibrated)):
        data = task.load_eval_data(out / "test", scene)
        for name, factory in task.classical_methods().items():
            metrics = task.evaluate(factory(scene), data)
            result[f"{name}_{label}"] = {
                "accuracy": metrics["accuracy"],
                "accuracy_by_duration": metrics["accuracy_by_duration"],
            }
    print(json.dumps(result, indent=2, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
