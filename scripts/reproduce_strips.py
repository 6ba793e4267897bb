"""Reproduce the strip-array paper's figures with the classical estimators.

The paper (seed 000) reports Pearson r = 0.86 between the estimated and simulated pressure
profile for two spherical stimuli on a 16 x 16 grid, and r = 0.92 for one sphere on the real
5 x 5 prototype. This script simulates both scenes on held-out seeds and prints mean r (and the
other metrics) for every classical estimator, beside the paper's values.

    python scripts/reproduce_strips.py [--n 4000] [--seed 2026] [--json results/reproduce_strips.json]
"""

from __future__ import annotations

import argparse
import sys
from functools import partial

from synth.dataset import simulate_shard
from synth.io import atomic_write_json
from synth.scene import load_scene
from tactile_learn.tasks import get_task
from tactile_learn.tasks.base import EvalData
from tactile_learn.timing import timed

PAPER = {"strips16": 0.86, "strips5": 0.92}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=4000, help="frames per scene")
    parser.add_argument("--seed", type=int, default=2026, help="held-out seed")
    parser.add_argument("--json", default=None, help="write the results here")
    args = parser.parse_args(argv)
    task = get_task("strips")
    rows = []
    for name, paper_r in PAPER.items():
        scene = load_scene(name)
        arrays = simulate_shard(scene, args.seed, 0, args.n)
        extra = {k: v for k, v in arrays.items() if k.startswith("latent_")}
        data = EvalData(arrays["readings"], {"pressure": arrays["pressure"]}, scene, extra, f"{name} seed {args.seed}")
        for method, factory in task.classical_methods().items():
            metrics, seconds = timed(partial(task.evaluate, factory(scene), data))
            rows.append(
                {
                    "scene": name,
                    "method": method,
                    "paper_r": paper_r,
                    "pearson_r_mean": metrics["pearson_r_mean"],
                    "pearson_r_median": metrics["pearson_r_median"],
                    "nrmse": metrics["nrmse"],
                    "peak_err_mm_median": metrics["peak_err_mm_median"],
                    "seconds": seconds,
                }
            )
    print(
        f"{'scene':10s} {'method':13s} {'paper r':>8s} {'r mean':>7s} {'r median':>8s} "
        f"{'NRMSE':>6s} {'peak err mm':>11s}"
    )
    for r in rows:
        print(
            f"{r['scene']:10s} {r['method']:13s} {r['paper_r']:8.2f} {r['pearson_r_mean']:7.3f} "
            f"{r['pearson_r_median']:8.3f} {r['nrmse']:6.3f} {r['peak_err_mm_median']:11.2f}"
        )
    if args.json:
        atomic_write_json(args.json, {"n": args.n, "seed": args.seed, "rows": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
