"""Accuracy per contact duration on contact pixels only, for a few methods, on one held-out set.

A check with more touches than the model cards' test sets, for the durations where two methods
are close (e.g. the learned thermal_wns model against the physics fit at 2 s)::

    tactile-learn generate --scene thermal_wns --n 1000 --seed 13 --out data/thermal_wns-test2
    python scripts/thermal_duration_check.py --data data/thermal_wns-test2 \\
        --duration 0.5 --duration 1.0 --duration 2.0 --method thermal_wns --method physics_fit \\
        --json results/thermal_wns_durations.json
"""

from __future__ import annotations

import argparse
import json
from functools import partial

from synth.io import atomic_write_json
from tactile_learn.methods import resolve_method
from tactile_learn.tasks.thermal import ThermalTask, class_names, thermal_metrics, view
from tactile_learn.timing import timed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", required=True, help="held-out dataset folder from generate")
    parser.add_argument("--method", action="append", required=True, help="method name or model (repeatable)")
    parser.add_argument("--duration", type=float, action="append", required=True, help="contact duration (s)")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    task = ThermalTask()
    data = task.load_eval_data(args.data)
    materials = data.scene.sensor.material_list
    labels = data.truth["label"]
    contact = labels < len(class_names(data.scene)) - 1
    rows = []
    for method in args.method:
        estimator = resolve_method("thermal", method, data.scene)
        for duration in args.duration:
            x, valid = view(data, duration)
            keep = valid & contact
            predicted, seconds = timed(partial(estimator.predict_proba, x[keep]))  # type: ignore[attr-defined]
            metrics = thermal_metrics(predicted, labels[keep], materials)
            n = int(keep.sum())
            row = {
                "method": method,
                "duration_s": duration,
                "n_contact_pixels": n,
                "accuracy": metrics["accuracy"],
                "errors": round((1.0 - metrics["accuracy"]) * n),
                "seconds": seconds,
            }
            rows.append(row)
            print(json.dumps(row), flush=True)
    if args.json:
        atomic_write_json(args.json, {"data": args.data, "rows": rows})


if __name__ == "__main__":
    main()
