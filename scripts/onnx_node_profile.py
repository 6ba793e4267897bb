"""Where a model's batch-1 time goes: onnxruntime's own profiler, summed per node kind.

For each model, the graph ``predict`` runs (cut down to its first output,
:func:`~tactile_learn.onnx_prune.first_output_graph`, and fused, :mod:`tactile_learn.onnx_fuse`) under
the card's session options (one
thread), ``--calls`` batch-1 calls on simulated frames of the model's scene with
``SessionOptions.enable_profiling``; prints, per node kind (op type after onnxruntime's own
fusions), the number of nodes and the median time per call, and the share of the whole run's
time that no node accounts for (the session's own per-call cost). Profiled calls are slower than
plain ones (the profiler's bookkeeping): read the shares, not the totals.

    python scripts/onnx_node_profile.py models/strips16.onnx models/strips16_small.onnx --json results/x.json
    python scripts/onnx_node_profile.py models/strips16.onnx --batch 1024 --calls 60
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from collections import defaultdict  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from synth.dataset import simulate_shard  # noqa: E402
from tactile_learn.bench import record_run  # noqa: E402
from tactile_learn.onnx_fuse import fused_model_bytes  # noqa: E402
from tactile_learn.onnx_prune import first_output_graph  # noqa: E402
from tactile_learn.runtime import OnnxEstimator  # noqa: E402


def profile_model(path: Path, calls: int, batch: int = 1, fuse: bool = True, seed: int = 909090) -> dict[str, Any]:
    """Per node kind: nodes and median us per call of ``batch`` frames; plus the run's per-call total."""
    import onnxruntime as ort

    estimator = OnnxEstimator(path, threads=1).prepare()
    frames = simulate_shard(estimator.scene_, seed, 0, 64)[estimator._task().input_key].astype(np.float32)
    if batch > 1:
        frames = np.resize(frames, (batch, *frames.shape[1:]))
    model = first_output_graph(path) or path.read_bytes()
    if fuse:  # as predict runs it
        model = fused_model_bytes(model)
    with tempfile.TemporaryDirectory() as tmp:
        options = estimator._session_options()
        options.enable_profiling = True
        options.profile_file_prefix = str(Path(tmp) / "profile")
        options.optimized_model_filepath = str(Path(tmp) / "optimized.onnx")
        session = ort.InferenceSession(model, sess_options=options, providers=["CPUExecutionProvider"])
        name = session.get_inputs()[0].name
        for i in range(calls):
            start = 0 if batch > 1 else i % len(frames)
            session.run(None, {name: frames[start : start + batch]})
        events = json.loads(Path(session.end_profiling()).read_text())
    per_node: dict[str, list[float]] = defaultdict(list)
    kind_of: dict[str, str] = {}
    run_totals: list[float] = []
    for event in events:
        if event.get("cat") == "Session" and event.get("name") == "model_run":
            run_totals.append(float(event["dur"]))
        elif event.get("cat") == "Node" and event["name"].endswith("_kernel_time"):
            node = event["name"][: -len("_kernel_time")]
            kind_of[node] = str(event["args"]["op_name"])
            per_node[node].append(float(event["dur"]))
    # per kind and call: the sum over the kind's nodes (every node runs once a call)
    per_kind: dict[str, np.ndarray] = {}
    for node, durations in per_node.items():
        kind = kind_of[node]
        per_kind[kind] = per_kind.get(kind, 0.0) + np.asarray(durations)
    nodes = {kind: sum(1 for k in kind_of.values() if k == kind) for kind in per_kind}
    warm_nodes = {node: float(np.median(np.asarray(d)[calls // 5 :])) for node, d in per_node.items()}
    slowest = dict(sorted(warm_nodes.items(), key=lambda item: -item[1])[:12])
    warm = slice(calls // 5, None)  # the first calls allocate
    kinds = {
        kind: {"nodes": nodes[kind], "median_us": float(np.median(by_call[warm]))} for kind, by_call in per_kind.items()
    }
    total = float(np.median(np.asarray(run_totals)[warm]))
    in_nodes = sum(entry["median_us"] for entry in kinds.values())
    return {
        "run_median_us": total,
        "nodes": sum(entry["nodes"] for entry in kinds.values()),
        "outside_nodes_us": total - in_nodes,
        "kinds": dict(sorted(kinds.items(), key=lambda item: -item[1]["median_us"])),
        "slowest_nodes_us": {f"{node} ({kind_of[node]})": us for node, us in slowest.items()},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="+", type=Path)
    parser.add_argument("--calls", type=int, default=2000)
    parser.add_argument("--batch", type=int, default=1, help="frames per call (1: single frames)")
    parser.add_argument("--no-fuse", action="store_true", help="the graph as the file holds it (no load-time fusions)")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    load = os.getloadavg()[0]
    result: dict[str, Any] = {}
    for path in args.models:
        report = profile_model(path, args.calls, args.batch, fuse=not args.no_fuse)
        result[str(path)] = report
        print(
            f"{path}: {report['nodes']} nodes, run of {args.batch} frame(s) {report['run_median_us']:.1f} us "
            f"(profiled), outside nodes {report['outside_nodes_us']:.1f} us"
        )
        for kind, entry in report["kinds"].items():
            print(f"  {kind:24s} {entry['nodes']:3d} nodes {entry['median_us']:7.1f} us")
        print("  slowest nodes: " + ", ".join(f"{k} {v:.0f}" for k, v in report["slowest_nodes_us"].items()))
    record_run(result, "onnx_node_profile.py", argv, load, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
