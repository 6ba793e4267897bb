"""How far apart are issue 12's floors for one estimator? The simplest hedge between the default strip
model and the paper's rule, ``(1 - w) * strips16 + w * intersection`` (maps in kPa, frame by frame), for
``w`` from 0 to 1: r on two spheres (floor 0.96) against the margin over the best classical rule on the
ood suite and on a round of unseen shapes (floor +0.05, every family). A diagnostic, nothing shipped::

    python scripts/strips_blend_tradeoff.py --suites strips16_ood strips16_unseen5 \\
        --json results/strips_experts/blend.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from synth.scene import load_scene
from synth.suite import load_suite
from tactile_learn.methods import resolve_method
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.suites import suite_eval_data
from tactile_learn.tasks import get_task

WEIGHTS = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0)


def blend_scores(
    model_maps: np.ndarray, rule_maps: np.ndarray, data: Any, weights: tuple[float, ...] = WEIGHTS
) -> list[float]:
    """r mean (the task's metric) of every blend weight on ``data``."""
    task = get_task("strips")
    return [float(task.metrics((1.0 - w) * model_maps + w * rule_maps, data)["pearson_r_mean"]) for w in weights]


def evaluate(
    model: str, suites: list[str], n: int, seeds: list[int], two_spheres: str, log: Any = print
) -> dict[str, Any]:
    task = get_task("strips")
    base = load_scene("strips16")
    net = OnnxEstimator(model, threads=1).prepare()
    rule = resolve_method("strips", "intersection", base)
    projection = resolve_method("strips", "projection", base)
    data = task.load_eval_data(two_spheres)
    result: dict[str, Any] = {
        "weights": list(WEIGHTS),
        "two_spheres": blend_scores(net.predict(data.inputs), rule.predict(data.inputs), data),
        "suites": {},
    }
    log("two spheres", [round(v, 4) for v in result["two_spheres"]])
    for name in suites:
        suite = load_suite(name)
        margins: dict[str, list[list[float]]] = {f.name: [] for f in suite.families}
        for seed in seeds:
            for fam, frames in suite_eval_data(suite, n, seed).items():
                rule_maps = rule.predict(frames.inputs)
                best = max(
                    task.metrics(rule_maps, frames)["pearson_r_mean"],
                    task.metrics(projection.predict(frames.inputs), frames)["pearson_r_mean"],
                )
                scores = blend_scores(net.predict(frames.inputs), rule_maps, frames)
                margins[fam].append([s - best for s in scores])
        per_family = {fam: np.mean(rows, axis=0).tolist() for fam, rows in margins.items()}
        worst_seed = {fam: np.max(rows, axis=0) for fam, rows in margins.items()}  # below at every seed: < 0
        result["suites"][name] = {
            "per_family": per_family,
            "mean_margin": np.mean(list(per_family.values()), axis=0).tolist(),
            "families_below": [int(sum(v[i] < 0 for v in worst_seed.values())) for i in range(len(WEIGHTS))],
        }
        log(
            name, [round(v, 4) for v in result["suites"][name]["mean_margin"]], result["suites"][name]["families_below"]
        )
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default="models/strips16.onnx")
    parser.add_argument("--suites", nargs="+", default=["strips16_ood", "strips16_unseen5"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[5151, 6262])
    parser.add_argument("--n", type=int, default=600)
    parser.add_argument("--two-spheres", default="data/strips16-test")
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    result = evaluate(args.model, args.suites, args.n, args.seeds, args.two_spheres)
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
