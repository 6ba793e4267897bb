"""Per-frame overhead of every estimator: batch-1 latency against the per-frame cost at batch 1024.

For each task (strips, fsr, thermal, capacitive) and each of its methods (classical, and every
shipped ONNX model of the task's sensor under onnxruntime with 1 thread), on held-out frames of the
task's default scene, in interleaved rounds (every method sees the same machine load): ``--per-round``
calls at batch 1, then one call at batch 1024. Reported per method, as medians over all rounds:

- ``b1_us``: latency of one ``predict`` call on one frame (us);
- ``b1024_us_per_frame``: the batch-1024 call's time over 1024 (us);
- ``overhead_ratio``: ``b1_us / b1024_us_per_frame`` (the target is <= 3 where physically
  possible; an onnxruntime call alone costs ~12 us, which bounds a small network's ratio);
- the same for ``stream`` (:class:`tactile_learn.stream.FrameStream`: checks and set-up once per
  session, the documented fast path for single frames) where it applies.

    python scripts/latency_overhead.py --json results/latency_overhead.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from synth.io import atomic_write_text
from synth.scene import Scene, load_scene
from tactile_learn.bench import _bench_data, _same_sensor, machine_info
from tactile_learn.methods import shipped_models
from tactile_learn.runtime import OnnxEstimator, read_card
from tactile_learn.tasks import get_task

TASKS = ("strips", "fsr", "thermal", "capacitive")


def methods_of(task_name: str, scene: Scene) -> dict[str, Any]:
    """Every classical method and every shipped model of ``scene``'s sensor (1 thread)."""
    task = get_task(task_name)
    found: dict[str, Any] = {name: factory(scene) for name, factory in task.classical_methods().items()}
    for name, path in sorted(shipped_models(task_name).items()):
        card = read_card(path)
        if card["scene_digest"] == scene.digest:
            found[f"{name}.onnx"] = OnnxEstimator(path, threads=1)
        elif _same_sensor(task_name, card["scene"], scene):
            found[f"{name}.onnx"] = OnnxEstimator(path, threads=1, scene=scene)
    return found


def measure(
    calls: dict[str, Callable[[np.ndarray], Any]], frames: np.ndarray, rounds: int, per_round: int
) -> dict[str, dict[str, float]]:
    big = np.ascontiguousarray(np.resize(frames, (1024, *frames.shape[1:])), dtype=np.float32)
    singles = [np.ascontiguousarray(frames[i : i + 1], dtype=np.float32) for i in range(len(frames))]
    for call in calls.values():  # warm-up: sessions, caches, lazily fitted state
        for i in range(20):
            call(singles[i % len(singles)])
        call(big)
    one: dict[str, list[float]] = {k: [] for k in calls}
    batch: dict[str, list[float]] = {k: [] for k in calls}
    for r in range(rounds):
        for name, call in calls.items():
            for k in range(per_round):
                frame = singles[(r * per_round + k) % len(singles)]
                start = time.perf_counter()
                call(frame)
                one[name].append(time.perf_counter() - start)
            start = time.perf_counter()
            call(big)
            batch[name].append((time.perf_counter() - start) / len(big))
    out = {}
    for name in calls:
        b1, per_frame = float(np.median(one[name]) * 1e6), float(np.median(batch[name]) * 1e6)
        out[name] = {"b1_us": b1, "b1024_us_per_frame": per_frame, "overhead_ratio": b1 / per_frame}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    parser.add_argument("--frames", type=int, default=64, help="held-out frames (touches for thermal) per task")
    parser.add_argument("--rounds", type=int, default=30)
    parser.add_argument("--per-round", type=int, default=30)
    parser.add_argument("--no-stream", action="store_true", help="time predict only, not the streaming fast path")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    load_before = os.getloadavg()[0]
    result: dict[str, Any] = {"machine": machine_info(), "tasks": {}}
    for task_name in args.tasks:
        task = get_task(task_name)
        data = _bench_data(task_name, None, args.frames, None)
        frames = np.asarray(task.latency_inputs(data), dtype=np.float32)
        calls: dict[str, Callable[[np.ndarray], Any]] = {}
        for name, est in methods_of(task_name, load_scene(task.default_scene)).items():
            calls[name] = est.predict
            if not args.no_stream:
                from tactile_learn.stream import FrameStream

                calls[f"{name} [stream]"] = FrameStream(est).predict
        result["tasks"][task_name] = measure(calls, frames, args.rounds, args.per_round)
        for name, row in result["tasks"][task_name].items():
            print(
                f"{task_name:10s} {name:34s} b1 {row['b1_us']:8.1f} us  b1024 {row['b1024_us_per_frame']:8.2f} us/frame"
                f"  ratio {row['overhead_ratio']:6.1f}",
                flush=True,
            )
    result["load_average_1min"] = [load_before, os.getloadavg()[0]]
    result["command"] = "python scripts/latency_overhead.py " + " ".join(argv if argv is not None else sys.argv[1:])
    print(f"load average (1 min) before / after: {result['load_average_1min']}")
    if args.json:
        atomic_write_text(args.json, json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
