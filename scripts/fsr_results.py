"""Issue 5's must-show figures for the FSR film: every method on held-out frames and films.

Generates (if missing) a training set (seed 1), a validation set (seed 2) and a test set (seed 3)
of the ``fsr6`` scene: the test set's films (gain draws) are not in the training set. Trains the
learned localiser with the generic loop (if no ``--run`` is given), then evaluates on the test set:

- triangulation (the paper's kind: half-space kernel, force calibrated on the nominal film),
  triangulation_fit (the same closed form with a fitted effective kernel) and the learned model
  (torch, and ONNX when ``--onnx`` names an exported model);
- uncalibrated films, then calibrated: each test film is calibrated from ``--presses`` known
  presses on top of each sensor (2-8 N, with the film's own repeatability and ADC noise), and its
  frames are mapped to the nominal film (``to_nominal_film``) before estimating;
- latency per frame at batch 1 (median of repeated single-frame ``predict`` calls, input checks
  included) for every method.

Usage::

    python scripts/fsr_results.py --work data/fsr --run runs/fsr --json results/fsr.json
    python scripts/fsr_results.py --work data/fsr --run runs/fsr --onnx models/fsr.onnx
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from synth.dataset import Dataset, generate
from synth.io import atomic_write_json
from synth.scene import load_scene
from synth.sensors import fsr
from tactile_learn.estimators.base import Estimator
from tactile_learn.tasks.fsr import (
    PAPER_FORCE_ACCURACY,
    PAPER_SPATIAL_RESOLUTION_MM,
    FsrTask,
    calibrate_gains,
    fsr_metrics,
    to_nominal_film,
)
from tactile_learn.timing import interleaved_times, summary_us

SPLITS = {"train": (1, 200_000), "val": (2, 5_000), "test": (3, 20_000)}
SHOWN = (
    "loc_err_mm_median",
    "loc_err_mm_p95",
    "force_err_pct_median",
    "force_accuracy",
    "detect_accuracy",
    "loc_err_mm_median_inside",
    "loc_err_mm_p95_inside",
    "force_accuracy_inside",
    "loc_err_mm_median_film",
    "loc_err_mm_p95_film",
    "detect_accuracy_film",
)


def ensure_data(work: Path, n_train: int) -> dict[str, Path]:
    scene = load_scene("fsr6")
    paths = {}
    for split, (seed, n) in SPLITS.items():
        path = work / split
        n = n_train if split == "train" else n
        if not (path / "manifest.json").is_file():
            print(f"generating {split}: {n} frames, seed {seed}", flush=True)
            generate(scene, n, seed, path)
        paths[split] = path
    return paths


def learned_estimators(run: Path, onnx: Path | None) -> dict[str, Estimator]:
    from tactile_learn.torch_estimator import TorchEstimator

    torch_net = TorchEstimator.from_checkpoint(run, load_scene("fsr6"), threads=1)
    methods: dict[str, Estimator] = {"learned (torch)": torch_net}
    if onnx is not None:
        from tactile_learn.runtime import OnnxEstimator

        methods[f"learned ({onnx.name})"] = OnnxEstimator(onnx, threads=1).prepare()
    return methods


def calibrate_films(
    readings: np.ndarray, film_id: np.ndarray, gains: np.ndarray, presses: int, seed: int
) -> tuple[np.ndarray, float]:
    """Map every film's frames to the nominal film with gains estimated from ``presses`` known
    presses per sensor on that film; returns the mapped readings and the rms gain error."""
    scene = load_scene("fsr6")
    config: fsr.FsrConfig = scene.sensor
    sim = fsr.make_simulator(scene)
    pos = fsr.sensor_positions(config.layout)
    rng = np.random.default_rng(seed)
    out = readings.astype(np.float32).copy()
    errors = []
    for film in np.unique(film_id):
        rows = film_id == film
        true = gains[rows][0].astype(np.float64)
        xy = np.repeat(pos, presses, axis=0) + rng.normal(0.0, 0.5, (6 * presses, 2))  # placed by hand
        force = rng.uniform(2.0, 8.0, 6 * presses)
        press_gain = true * (1.0 + config.film.repeatability * rng.uniform(-1.0, 1.0, (len(force), 6)))
        measured = sim.forward(xy, force, 4.0, gains=press_gain, rng=rng)
        estimate, _ = calibrate_gains(measured, xy, force, config)
        errors.append(estimate / true - 1.0)
        out[rows] = to_nominal_film(readings[rows], config, estimate)
    return out, float(np.sqrt(np.mean(np.square(errors))))


def latency_us(estimator: Estimator, frame: np.ndarray, repeats: int = 300) -> float:
    """Median batch-1 latency of ``predict`` on ``frame`` (us), after 20 warm-up calls."""
    times = interleaved_times({"predict": estimator.predict}, frame, rounds=repeats, warmup=20)
    return summary_us(times["predict"])["median_us"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--work", type=Path, default=Path("data/fsr"), help="dataset folder (train/val/test)")
    parser.add_argument("--run", type=Path, default=Path("runs/fsr"), help="training run (trained if missing)")
    parser.add_argument("--onnx", type=Path, default=None, help="exported model to evaluate as well")
    parser.add_argument("--n-train", type=int, default=SPLITS["train"][1])
    parser.add_argument("--size", default="small")
    parser.add_argument("--presses", type=int, default=3, help="calibration presses per sensor")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)

    paths = ensure_data(args.work, args.n_train)
    if not (args.run / "model.pt").is_file():
        from tactile_learn.train import TrainConfig, train

        print(f"training {args.size} into {args.run}", flush=True)
        train(TrainConfig("fsr", str(paths["train"]), str(args.run), val=str(paths["val"]), size=args.size, threads=1))

    task = FsrTask()
    scene = load_scene("fsr6")
    test = Dataset(paths["test"])
    arrays = test.arrays()
    methods: dict[str, Estimator] = {name: factory(scene) for name, factory in task.classical_methods().items()}
    methods.update(learned_estimators(args.run, args.onnx))
    calibrated, gain_rms = calibrate_films(
        arrays["readings"], arrays["latent_film_id"], arrays["latent_gain"], args.presses, seed=11
    )
    n_films = len(np.unique(arrays["latent_film_id"]))
    frame = arrays["readings"][np.argmax(arrays["force_n"])][None]
    results: dict[str, Any] = {
        "test": {"path": str(paths["test"]), "seed": test.seed, "frames": len(test), "films": n_films},
        "calibration": {"presses_per_sensor": args.presses, "gain_rms_error": gain_rms},
        "paper": {
            "force_accuracy": PAPER_FORCE_ACCURACY,
            "spatial_resolution_mm": PAPER_SPATIAL_RESOLUTION_MM,
        },
        "methods": {},
    }
    for name, estimator in methods.items():
        entry: dict[str, Any] = {}
        for label, readings in (("uncalibrated", arrays["readings"]), ("calibrated", calibrated)):
            m = fsr_metrics(estimator.predict(readings), arrays["xy_mm"], arrays["force_n"], scene.sensor.layout)
            entry[label] = {k: m[k] for k in SHOWN}
        entry["latency_us_batch1"] = latency_us(estimator, frame)
        results["methods"][name] = entry
        print(f"{name}: done", flush=True)

    print(f"\ntest set: {len(test)} frames, {n_films} films unseen in training (seed {test.seed})")
    print(f"calibration: {args.presses} presses per sensor, rms gain error {100 * gain_rms:.2f} %")
    print("paper's conditions (inside the triangles, 1-10 N):  paper: 2.5 mm, 88.23 %")
    header = f"{'method':34s} {'films':12s} {'median':>7s} {'p95':>6s} {'F med%':>7s} {'F acc':>6s} "
    header += f"{'med in':>7s} {'med film':>8s} {'latency':>9s}"
    print(header)
    for name, entry in results["methods"].items():
        for label in ("uncalibrated", "calibrated"):
            m = entry[label]
            print(
                f"{name:34s} {label:12s} {m['loc_err_mm_median']:7.3f} {m['loc_err_mm_p95']:6.2f} "
                f"{m['force_err_pct_median']:7.2f} {m['force_accuracy']:6.4f} "
                f"{m['loc_err_mm_median_inside']:7.3f} {m['loc_err_mm_median_film']:8.2f} "
                f"{entry['latency_us_batch1']:7.1f}us"
            )
    if args.json:
        atomic_write_json(args.json, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
