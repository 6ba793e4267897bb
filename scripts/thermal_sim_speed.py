"""Thermal simulator throughput: the fast record path against the whole-record reference, one run.

Both paths simulate the same touches (same seed per repeat, interleaved, the order alternating), as
``generate`` does (chunks of ``synth.dataset.CHUNK`` touches, noise and ADC on); reported are
median touches/s over the repeats (wall clock and CPU time), the median of the per-repeat ratios
(and, for a busy machine, the ratio of each path's fastest repeat),
whether the two paths' arrays are byte-identical, and the largest difference of their clean
(noise-free) curves. One thread (BLAS/OpenMP pinned), as a dataset worker runs.

A third path, ``training``, is what ``train --stream --stream-pixels 4`` simulates: the same
touches with only the 4 pixels per touch that training reads (``synth.sensors.thermal.subset``);
its rate is given in touches/s (4 pixel curves each, the curves training takes from a touch) and
in pixel curves/s, beside the whole-array paths' (16 curves per touch, 4 of them read).

    python scripts/thermal_sim_speed.py                       # results/thermal_sim_speed.json
    python scripts/thermal_sim_speed.py --scene thermal_wns --repeats 5 --json /dev/stdout
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from synth.dataset import CHUNK  # noqa: E402
from synth.io import atomic_write_json  # noqa: E402
from synth.scene import load_scene  # noqa: E402
from synth.sensors.thermal import make_simulator  # noqa: E402

#: pixels per touch training reads (tactile_learn.tasks.thermal trains on 4 random pixels of a touch)
TRAIN_PIXELS = 4


def measure(scene_name: str, touches: int, repeats: int) -> dict[str, Any]:
    scene = load_scene(scene_name)
    paths = {
        "reference": make_simulator(scene, reference=True),
        "fast": make_simulator(scene),
        "training": make_simulator(scene, pixels=TRAIN_PIXELS),
    }
    for sim in paths.values():  # warm-up: imports, caches
        sim.simulate(16, np.random.default_rng(0))
    wall: dict[str, list[float]] = {k: [] for k in paths}
    cpu: dict[str, list[float]] = {k: [] for k in paths}
    identical = True
    for rep in range(repeats):
        order = list(paths) if rep % 2 == 0 else list(paths)[::-1]
        outs = {}
        for name in order:
            w0, c0 = time.perf_counter(), time.process_time()
            outs[name] = paths[name].simulate(touches, np.random.default_rng(1000 + rep))
            wall[name].append(time.perf_counter() - w0)
            cpu[name].append(time.process_time() - c0)
        identical &= all(np.array_equal(outs["fast"][k], outs["reference"][k]) for k in outs["reference"])
    clean = {k: make_simulator(scene.with_noise(False), reference=(k == "reference")) for k in ("reference", "fast")}
    draws = clean["fast"].draw(min(touches, 256), np.random.default_rng(7))
    diff = float(np.abs(clean["fast"].clean_readings(draws) - clean["reference"].clean_readings(draws)).max())
    cfg = scene.sensor
    result: dict[str, Any] = {
        "scene": scene.name,
        "pixels": cfg.n_pixels,
        "samples": cfg.readout.n_samples,
        "touches_per_call": touches,
        "repeats": repeats,
        "identical_bytes": bool(identical),
        "clean_max_abs_diff_k": diff,
    }
    curves = {"reference": cfg.n_pixels, "fast": cfg.n_pixels, "training": TRAIN_PIXELS}
    for clock, times in (("wall", wall), ("cpu", cpu)):
        result[f"touches_per_s_{clock}"] = {k: round(touches / float(np.median(v)), 1) for k, v in times.items()}
        result[f"pixel_curves_per_s_{clock}"] = {
            k: round(curves[k] * touches / float(np.median(v)), 1) for k, v in times.items()
        }
        for path, key in (("fast", "speedup"), ("training", "training_speedup")):
            ratios = np.array(times["reference"]) / np.array(times[path])
            result[f"{key}_{clock}"] = round(float(np.median(ratios)), 2)
            result[f"{key}_{clock}_range"] = [round(float(ratios.min()), 2), round(float(ratios.max()), 2)]
            # the least disturbed repeat of each path (a busy machine slows some repeats a lot)
            result[f"{key}_{clock}_best_of"] = round(float(np.min(times["reference"]) / np.min(times[path])), 2)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", action="append", default=None, help="scene(s) (default: thermal)")
    parser.add_argument("--touches", type=int, default=CHUNK, help="touches per simulate call (generate's chunk)")
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--json", default="results/thermal_sim_speed.json")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    results = [measure(name, args.touches, args.repeats) for name in args.scene or ["thermal"]]
    report = {
        "command": "python scripts/thermal_sim_speed.py",
        "threads": 1,
        "load_average_1min": [round(load_before, 2), round(os.getloadavg()[0], 2)],
        "note": "reference: ThermalSimulator(reference=True), the whole-record path of the commit before the fast one",
        "results": results,
    }
    for r in results:
        print(
            f"{r['scene']}: {r['pixels']} px x {r['samples']} samples: reference "
            f"{r['touches_per_s_wall']['reference']} touches/s, fast {r['touches_per_s_wall']['fast']} touches/s "
            f"(wall), speed-up x{r['speedup_wall']} wall / x{r['speedup_cpu']} CPU (median of {r['repeats']}; best-of "
            f"x{r['speedup_wall_best_of']} / x{r['speedup_cpu_best_of']}), "
            f"identical bytes: {r['identical_bytes']}, clean curves within {r['clean_max_abs_diff_k']:.1e} K; "
            f"training stream ({TRAIN_PIXELS} px/touch) {r['touches_per_s_wall']['training']} touches/s, "
            f"x{r['training_speedup_wall']} wall / x{r['training_speedup_cpu']} CPU against the reference"
        )
    if args.json == "/dev/stdout":
        import json

        print(json.dumps(report, indent=2))
    else:
        atomic_write_json(args.json, report)


if __name__ == "__main__":
    main()
