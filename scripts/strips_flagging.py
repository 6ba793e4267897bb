"""How well does a general strip model's readings residual flag frames unlike its training data?

In-family frames: the model's own held-out test set (its training distribution, another seed) and
every family of the ``strips16_ood`` suite (held-out shapes of the library: the model should answer
them, not flag them). Out-of-family frames: every family of ``strips16_outliers`` (more contacts
than ever trained on, heavier presses, another cover, drifted strips). For each set: the share of
frames flagged (residual above the card's threshold), the model's r on flagged and unflagged frames,
and the r of the documented fallback (the intersection rule) on the flagged ones.

    python scripts/strips_flagging.py --model models/strips16.onnx --test data/mixed-test \\
        --json results/strips_flagging.json
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from synth.suite import load_suite
from tactile_learn.estimators.classical.intersection import IntersectionEstimator
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.strips_guard import CheckedStripModel
from tactile_learn.suites import SUITE_SEED, suite_eval_data
from tactile_learn.tasks import get_task
from tactile_learn.tasks.base import EvalData


def _row(checked: CheckedStripModel, data: EvalData) -> dict[str, float]:
    out = checked.check(data.inputs)
    truth = data.truth["pressure"]
    flagged = out["flagged"]
    r_learned = pearson_per_frame(out["learned"], truth)
    r_fallback = pearson_per_frame(IntersectionEstimator(data.scene).prepare().predict(data.inputs), truth)

    def mean(values: np.ndarray, mask: np.ndarray) -> float:
        picked = values[mask & np.isfinite(values)]
        return float(picked.mean()) if picked.size else float("nan")

    return {
        "frames": len(flagged),
        "flagged_share": float(flagged.mean()),
        "residual_median": float(np.median(out["residual"])),
        "balance_median": float(np.median(out["balance"])),
        "r_learned_unflagged": mean(r_learned, ~flagged),
        "r_learned_flagged": mean(r_learned, flagged),
        "r_fallback_flagged": mean(r_fallback, flagged),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default="models/strips16.onnx")
    parser.add_argument("--test", required=True, help="held-out frames of the model's training distribution")
    parser.add_argument("--n", type=int, default=1000, help="frames per suite family")
    parser.add_argument("--seed", type=int, default=SUITE_SEED)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    checked = CheckedStripModel(args.model).prepare()
    task = get_task("strips")
    sets: dict[str, dict[str, dict[str, float]]] = {"in_family": {}, "out_of_family": {}}
    sets["in_family"]["training distribution (test set)"] = _row(checked, task.load_eval_data(args.test))
    for name, data in suite_eval_data(load_suite("strips16_ood"), args.n, args.seed).items():
        sets["in_family"][f"strips16_ood/{name}"] = _row(checked, data)
    for name, data in suite_eval_data(load_suite("strips16_outliers"), args.n, args.seed).items():
        sets["out_of_family"][f"strips16_outliers/{name}"] = _row(checked, data)
    summary = {group: float(np.mean([r["flagged_share"] for r in rows.values()])) for group, rows in sets.items()}
    result = {
        "model": args.model,
        "thresholds": checked.thresholds_,
        "seed": args.seed,
        "sets": sets,
        "mean_flagged_share": summary,
        "command": "python scripts/strips_flagging.py " + " ".join(argv if argv is not None else sys.argv[1:]),
    }
    print(f"thresholds {checked.thresholds_}")
    print("| set | frames | flagged | r learned (unflagged / flagged) | r intersection (flagged) |")
    print("|---|---:|---:|---:|---:|")
    for group, rows in sets.items():
        for name, r in rows.items():
            print(
                f"| {name} ({group.replace('_', ' ')}) | {r['frames']} | {100 * r['flagged_share']:.1f} % | "
                f"{r['r_learned_unflagged']:.3f} / {r['r_learned_flagged']:.3f} | {r['r_fallback_flagged']:.3f} |"
            )
    inside, outside = 100 * summary["in_family"], 100 * summary["out_of_family"]
    print(f"mean flagged: in-family {inside:.1f} %, out-of-family {outside:.1f} %")
    if args.json:
        from synth.io import atomic_write_json

        atomic_write_json(args.json, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
