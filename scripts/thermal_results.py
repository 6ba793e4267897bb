"""The thermal fingertip's must-show table on held-out simulated touches.

For one test dataset (generated with a seed the models never saw): accuracy, family accuracy and
contact accuracy by contact duration (0.25, 0.5, 1, 2 s) for every classical method, the oracle
(physics fit with each pixel's true sensor parameters) and any ONNX models given; the confusion
pairs with their effusivities; and the latency of each classifier per curve at batch 1.

    tactile-learn generate --scene thermal --n 300 --seed 11 --out data/thermal-test
    python scripts/thermal_results.py --data data/thermal-test --model models/thermal.onnx \
        --json results/thermal.json
"""

from __future__ import annotations

import argparse
import json
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from synth.io import atomic_write_json
from tactile_learn.estimators.base import Estimator
from tactile_learn.tasks.thermal import ThermalTask, oracle_accuracy_by_duration
from tactile_learn.timing import interleaved_times, summary_us, timed


def latency_ms(estimator: Estimator, x: np.ndarray, repeats: int = 30) -> float:
    """Median wall time of ``predict`` on one curve (batch 1), in ms, after a warm-up call."""
    times = interleaved_times({"predict": estimator.predict}, x, rounds=repeats, warmup=1)
    return summary_us(times["predict"])["median_us"] / 1e3


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", required=True, help="held-out dataset folder from generate")
    parser.add_argument("--model", action="append", default=[], help="ONNX model(s) to include")
    parser.add_argument("--limit", type=int, default=None, help="first N pixel rows only")
    parser.add_argument("--no-oracle", action="store_true", help="skip the (slow) oracle")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    task = ThermalTask()
    data = task.load_eval_data(args.data)
    if args.limit:
        data = data.subset(slice(0, args.limit))
    methods: dict[str, Estimator] = {name: f(data.scene) for name, f in task.classical_methods().items()}
    if args.model:
        from tactile_learn.runtime import OnnxEstimator

        for path in args.model:
            methods[Path(path).name] = OnnxEstimator(path).prepare()
    result: dict[str, Any] = {"data": args.data, "scene": data.scene.name, "n_pixels": len(data), "methods": {}}
    probe = data.inputs[:64]
    for name, est in methods.items():
        metrics, eval_seconds = timed(partial(task.evaluate, est, data))
        result["methods"][name] = {
            "accuracy": metrics["accuracy"],
            "accuracy_by_duration": metrics["accuracy_by_duration"],
            "family_accuracy_by_duration": metrics["family_accuracy_by_duration"],
            "contact_accuracy_by_duration": metrics["contact_accuracy_by_duration"],
            "confusion_pairs": metrics["confusion_pairs"][:8],
            "eval_seconds": eval_seconds,
            "latency_ms_batch1": latency_ms(est, probe),
        }
        print(name, json.dumps({k: result["methods"][name][k] for k in ("accuracy_by_duration", "latency_ms_batch1")}))
    if not args.no_oracle:
        result.update(oracle_accuracy_by_duration(data))
        print("oracle", json.dumps(result["oracle_accuracy_by_duration"]))
    if args.json:
        atomic_write_json(args.json, result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
