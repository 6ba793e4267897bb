"""Batch-1 latency of the strip methods, interleaved so that every method sees the same machine
load: rounds of ``--per-round`` calls per method, repeated, median per call over all rounds. Prints
the load average before and after (latency floors are measured on a quiet machine, load < 1).

    python scripts/strips_latency.py --rounds 200 --json results/strips_latency.json
    python scripts/strips_latency.py --models strips16 runs/NAME/model.onnx --rounds 200 --per-round 10
    python scripts/strips_latency.py --models strips16 runs/objects12-bundle --suite strips16_unseen12

``--models`` takes shipped names, the paths of exported ``.onnx`` files with their card beside them, or
known-objects bundles. ``--suite`` times every method on a suite's frames instead of two spheres.
``--before DIR`` times the same models from ``DIR`` (e.g. main's, beside re-exported ones) as the
runtime ran them before the load-time fusions (``OnnxEstimator(fuse=False)``), in the same rounds.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

from synth.dataset import simulate_shard
from synth.scene import load_scene
from synth.suite import load_suite
from tactile_learn.bench import record_run
from tactile_learn.methods import resolve_method
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.strips_guard import CheckedStripModel
from tactile_learn.suites import suite_eval_data
from tactile_learn.timing import interleaved_times, summary_us


def before_file_name(model: str) -> str:
    """The file in ``--before DIR`` that matches a model given by shipped name or by .onnx path."""
    return Path(model).name if model.endswith(".onnx") else f"{model}.onnx"


def timing_frames(suite_name: str | None, n: int = 512) -> np.ndarray:
    """The frames every method is timed on: ``n`` of the two-sphere scene (seed 909090), or ``n`` spread evenly
    over a suite's families (the same seed: a frame's cost may depend on its shape, e.g. which model a router
    picks)."""
    if suite_name is None:
        return np.asarray(simulate_shard(load_scene("strips16"), 909090, 0, n)["readings"], dtype=np.float32)
    suite = load_suite(suite_name)
    each = -(-n // len(suite.families))
    frames = [d.inputs for d in suite_eval_data(suite, each, 909090).values()]
    return np.ascontiguousarray(np.concatenate(frames)[:n], dtype=np.float32)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=200)
    parser.add_argument("--per-round", type=int, default=20)
    parser.add_argument(
        "--models",
        nargs="+",
        default=["strips16", "strips16_spheres"],
        help="shipped names or .onnx paths (card beside)",
    )
    parser.add_argument(
        "--before", type=Path, default=None, help="a folder with the same models to time beside them, unfused"
    )
    parser.add_argument(
        "--suite", default=None, help="time on this suite's frames (512 over its families) instead of two spheres"
    )
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    scene = load_scene("strips16")
    readings = timing_frames(args.suite)
    methods = {"intersection": resolve_method("strips", "intersection", scene)}
    for name in args.models:
        methods[f"{name} (onnxruntime, 1 thread)"] = resolve_method("strips", name, scene, threads=1)
        if args.before is not None:  # the runtime before the load-time fusions, on that folder's graph
            before_file = args.before / before_file_name(name)
            methods[f"{name} (before)"] = OnnxEstimator(before_file, threads=1, fuse=False).prepare()
    methods["strips16 checked (flags + fallback)"] = CheckedStripModel("models/strips16.onnx", threads=1).prepare()
    load_before = os.getloadavg()
    calls = {name: est.predict for name, est in methods.items()}
    times = interleaved_times(calls, readings, rounds=args.rounds, per_round=args.per_round, warmup=50)
    summaries = {k: summary_us(v) for k, v in times.items()}
    result = {
        "median_us": {k: v["median_us"] for k, v in summaries.items()},
        "p90_us": {k: v["p90_us"] for k, v in summaries.items()},
        "calls_per_method": args.rounds * args.per_round,
    }
    for name in methods:
        print(f"{name:40s} median {result['median_us'][name]:8.1f} us   p90 {result['p90_us'][name]:8.1f} us")
    record_run(result, "strips_latency.py", argv, load_before[0], args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
