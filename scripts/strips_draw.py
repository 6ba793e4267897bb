"""Issue 12's floors on an independent draw of the ``strips16_ood`` suite: a seed of your choosing.

The bench and the model cards evaluate the suite at its fixed seed; "independent shapes you have not
seen will be checked the same way" means fresh frames of every family at another seed. For each
model given, r per family against the best classical method of that family (intersection or
projection, whichever is higher there), the margin averaged over families and the families where the
model is not above the best classical method::

    python scripts/strips_draw.py --seed 5151 --n 600 models/strips16.onnx
    python scripts/strips_draw.py --seed 4242 --n 600 models/strips16.onnx old/strips16.onnx --json draw.json
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from synth.io import atomic_write_json
from synth.suite import load_suite
from tactile_learn.methods import resolve_method
from tactile_learn.suites import evaluate_suite, suite_eval_data

CLASSICAL = ("intersection", "projection")


def family_r(method: str, suite_name: str, n: int, seed: int) -> dict[str, float]:
    """Mean Pearson r of ``method`` on every family of a fresh draw (``n`` frames a family, ``seed``)."""
    suite = load_suite(suite_name)
    data = suite_eval_data(suite, n, seed)
    estimator = resolve_method("strips", method, suite.base, threads=1)
    families = evaluate_suite(estimator, data, "strips")["families"]
    return {family: float(m["pearson_r_mean"]) for family, m in families.items()}


def compare(r: dict[str, dict[str, float]], models: list[str]) -> dict[str, Any]:
    """Each model's mean r, margin over the best classical method per family, families not above it."""
    families = list(r[CLASSICAL[0]])
    best = {f: max(r[c][f] for c in CLASSICAL) for f in families}
    out: dict[str, Any] = {"best_classical": best}
    for model in models:
        margin = {f: r[model][f] - best[f] for f in families}
        out[model] = {
            "mean_r": float(np.mean([r[model][f] for f in families])),
            "margin": float(np.mean(list(margin.values()))),
            "not_above": {f: m for f, m in margin.items() if m <= 0.0},
            "families": r[model],
        }
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="+", help="shipped model names or .onnx files")
    parser.add_argument("--seed", type=int, required=True, help="the draw's seed (not the suite's own)")
    parser.add_argument("--n", type=int, default=600, help="frames per family (default 600)")
    parser.add_argument("--suite", default="strips16_ood")
    parser.add_argument("--json", help="also write the result here")
    args = parser.parse_args(argv)
    r: dict[str, dict[str, float]] = {}
    for method in [*CLASSICAL, *args.models]:
        start = time.perf_counter()
        r[method] = family_r(method, args.suite, args.n, args.seed)
        print(f"{method}: mean r {np.mean(list(r[method].values())):.4f} ({time.perf_counter() - start:.0f} s)")
    result = compare(r, args.models)
    for model in args.models:
        below = {f: round(m, 4) for f, m in result[model]["not_above"].items()}
        print(f"{model}: margin {result[model]['margin']:+.4f}, not above the best classical: {below or 'none'}")
    if args.json:
        atomic_write_json(args.json, {"suite": args.suite, "seed": args.seed, "n": args.n, **result})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
