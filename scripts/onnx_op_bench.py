"""Single onnxruntime nodes on a strip network's crossing features, timed in interleaved rounds.

The mixing blocks of the strip networks pool ``(B, 24, 16, 16)`` features along rows and columns and
add a row term to a column term. This times each candidate form alone in a one-node (or few-node)
graph, one thread, "extended" optimisation, io binding: a batch of one (median us per call) and a
batch of 1024 (median us per frame). ``empty`` is two ``ReduceMax`` and an ``Add`` of their small
outputs (what every broadcast variant computes first).

    python scripts/onnx_op_bench.py --json results/onnx_op_bench.json
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from tactile_learn.bench import record_run  # noqa: E402

SHAPE = (24, 16, 16)


def _graphs() -> dict[str, bytes]:
    from onnx import TensorProto, helper, numpy_helper

    axes = [numpy_helper.from_array(np.array([a], np.int64), f"axis{a}") for a in (2, 3)]
    full = ["B", *SHAPE]

    def model(nodes: list[Any], out: list[Any]) -> bytes:
        x = helper.make_tensor_value_info("x", TensorProto.FLOAT, full)
        y = helper.make_tensor_value_info("y", TensorProto.FLOAT, out)
        read = {name for n in nodes for name in n.input}
        graph = helper.make_graph(nodes, "g", [x], [y], [a for a in axes if a.name in read])
        return bytes(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)]).SerializeToString())

    rows, cols = ["B", 24, 16, 1], ["B", 24, 1, 16]
    pools = [helper.make_node("ReduceMax", ["x", "axis2"], ["c"]), helper.make_node("ReduceMax", ["x", "axis3"], ["r"])]
    node = helper.make_node
    return {
        "ReduceMean over columns (axis 2)": model([node("ReduceMean", ["x", "axis2"], ["y"])], cols),
        "AveragePool (16, 1)": model([node("AveragePool", ["x"], ["y"], kernel_shape=[16, 1])], cols),
        "ReduceMax over columns (axis 2)": model([node("ReduceMax", ["x", "axis2"], ["y"])], cols),
        "ReduceMean over rows (axis 3)": model([node("ReduceMean", ["x", "axis3"], ["y"])], rows),
        "AveragePool (1, 16)": model([node("AveragePool", ["x"], ["y"], kernel_shape=[1, 16])], rows),
        "empty: two pools, small Add": model([*pools, node("Add", ["r", "r"], ["y"])], rows),
        "row + column term (broadcast Add)": model([*pools, node("Add", ["r", "c"], ["y"])], full),
        "Expand row term, Add column term": model(
            [*pools, node("Shape", ["x"], ["s"]), node("Expand", ["r", "s"], ["e"]), node("Add", ["e", "c"], ["y"])],
            full,
        ),
        "Sum(x, row term, column term)": model([*pools, node("Sum", ["x", "r", "c"], ["y"])], full),
        "x + x (same shape Add)": model([*pools, node("Add", ["x", "x"], ["y"])], full),
    }


def _session(model: bytes) -> Any:
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    options.inter_op_num_threads = 1
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_EXTENDED
    return ort.InferenceSession(model, sess_options=options, providers=["CPUExecutionProvider"])


def time_graphs(graphs: dict[str, bytes], batch: int, rounds: int, calls: int, seed: int = 0) -> dict[str, float]:
    """Median us per frame of each graph on ``batch`` frames, ``calls`` calls a round, interleaved."""
    x = np.random.default_rng(seed).random((batch, *SHAPE), dtype=np.float32)
    bound = {}
    for name, model in graphs.items():
        session = _session(model)
        binding = session.io_binding()
        binding.bind_cpu_input("x", x)
        binding.bind_output("y")
        for _ in range(20):
            session.run_with_iobinding(binding)
        bound[name] = (session, binding)
    times: dict[str, list[float]] = {name: [] for name in graphs}
    for _ in range(rounds):
        for name, (session, binding) in bound.items():
            start = time.perf_counter()
            for _ in range(calls):
                session.run_with_iobinding(binding)
            times[name].append((time.perf_counter() - start) / calls / batch * 1e6)
    return {name: float(np.median(t)) for name, t in times.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    load = os.getloadavg()[0]
    graphs = _graphs()
    single = time_graphs(graphs, 1, args.rounds, 500)
    batched = time_graphs(graphs, 1024, max(3, args.rounds // 4), 3)
    result = {"b1_us": single, "b1024_us_per_frame": batched}
    for name in graphs:
        print(f"{name:36s} b1 {single[name]:6.2f} us   b1024 {batched[name]:6.3f} us/frame")
    record_run(result, "onnx_op_bench.py", argv, load, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
