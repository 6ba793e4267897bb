"""Add held-out metrics to a shipped model's card: on another dataset (e.g. the two-sphere test set
of the general strip model) or a suite (per family and their mean), with the command that measured
them, under ``metrics.<name>``.

    python scripts/card_metrics.py --model models/strips16.onnx --name two_spheres --data data/strips16-test
    python scripts/card_metrics.py --model models/strips16.onnx --name strips16_ood --suite strips16_ood
"""

from __future__ import annotations

import argparse
import sys

from synth.io import atomic_write_json
from tactile_learn.methods import resolve_method
from tactile_learn.provenance import dataset_record
from tactile_learn.runtime import card_path, read_card
from tactile_learn.tasks import get_task


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", required=True, help="MODEL.onnx with its card")
    parser.add_argument("--name", required=True, help="key under the card's metrics")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--data", help="a dataset folder")
    source.add_argument("--suite", help="a suite name or file (per-family metrics)")
    parser.add_argument("--n", type=int, default=None, help="with --suite: frames per family")
    args = parser.parse_args(argv)
    card = read_card(args.model)
    task = get_task(card["task"])
    command = "python scripts/card_metrics.py " + " ".join(argv if argv is not None else sys.argv[1:])
    if args.data:
        data = task.load_eval_data(args.data)
        values = task.evaluate(resolve_method(task.name, str(args.model), data.scene), data)
        entry = {"data": dataset_record(args.data, len(data)), "values": values}
    else:
        from synth.suite import load_suite
        from tactile_learn.suites import SUITE_SEED, evaluate_suite, suite_eval_data

        suite = load_suite(args.suite)
        frames = suite_eval_data(suite, args.n, SUITE_SEED)
        report = evaluate_suite(resolve_method(task.name, str(args.model), suite.base), frames, task.name)
        entry = {
            "suite": suite.name,
            "seed": SUITE_SEED,
            "n_frames_per_family": {k: len(v) for k, v in frames.items()},
            "families": report["families"],
            "mean_over_families": report["mean_over_families"],
        }
    card.setdefault("metrics", {})[args.name] = {**entry, "command": command}
    atomic_write_json(card_path(args.model), card)
    primary = task.primary_metric[0]
    values = entry.get("values") or entry["mean_over_families"]
    print(f"{args.model}: metrics.{args.name}.{primary} = {values[primary]:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
