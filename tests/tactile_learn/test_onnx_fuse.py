"""The load-time fusions (tactile_learn.onnx_fuse): fewer nodes, the same function to float32
rounding, and no rewrite where it would change the function (a broadcast sum, a convolution read
twice, a softplus threshold or scale that is not exact). The exported strip graphs:
tests/tactile_learn/nets/test_strips_deploy_fused.py."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from synth.dataset import simulate_shard
from tactile_learn.methods import shipped_models
from tactile_learn.onnx_fuse import SOFTPLUS_EXACT, fuse_for_onnxruntime
from tactile_learn.runtime import OnnxEstimator

onnx = pytest.importorskip("onnx")
ort = pytest.importorskip("onnxruntime")
helper, numpy_helper = onnx.helper, onnx.numpy_helper


def _session(model: bytes) -> ort.InferenceSession:
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_EXTENDED
    return ort.InferenceSession(model, sess_options=options, providers=["CPUExecutionProvider"])


def _topological(model: onnx.ModelProto) -> bool:
    known = {v.name for v in model.graph.input} | {t.name for t in model.graph.initializer} | {""}
    for node in model.graph.node:
        if not set(node.input) <= known:
            return False
        known |= set(node.output)
    return True


def _model(nodes: list, inputs: dict[str, list], initializers: dict[str, np.ndarray], out: list) -> onnx.ModelProto:
    graph = helper.make_graph(
        nodes,
        "g",
        [helper.make_tensor_value_info(k, onnx.TensorProto.FLOAT, v) for k, v in inputs.items()],
        [helper.make_tensor_value_info("y", onnx.TensorProto.FLOAT, out)],
        [numpy_helper.from_array(v.astype(np.float32), k) for k, v in initializers.items()],
    )
    return helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)])


def _conv_add_relu(z_shape: list, extra_reader: bool = False, z_last: bool = False) -> onnx.ModelProto:
    """Relu(Conv(x) + z), z = x2 * 1 of ``z_shape`` (its producer after the Conv when ``z_last``)."""
    rng = np.random.default_rng(0)
    conv = helper.make_node("Conv", ["x", "w", "b"], ["c"])
    scale = helper.make_node("Mul", ["x2", "one"], ["z"])
    add = helper.make_node("Add", ["c", "z"], ["a"])
    relu = helper.make_node("Relu", ["a"], ["r"] if extra_reader else ["y"])
    nodes = [conv, scale, add, relu] if z_last else [scale, conv, add, relu]
    if extra_reader:  # the Conv's output read twice: it must stay
        nodes.append(helper.make_node("Add", ["r", "c"], ["y"]))
    inits = {"w": rng.normal(size=(4, 3, 1, 1)), "b": rng.normal(size=4), "one": np.ones(1)}
    return _model(nodes, {"x": ["B", 3, 5, 5], "x2": ["B", *z_shape]}, inits, ["B", 4, 5, 5])


def _run(model: onnx.ModelProto, feeds: dict[str, np.ndarray]) -> np.ndarray:
    return np.asarray(_session(model.SerializeToString()).run(None, feeds)[0])


def test_conv_add_relu_becomes_one_fused_node_in_order() -> None:
    rng = np.random.default_rng(1)
    feeds = {
        "x": rng.normal(size=(2, 3, 5, 5)).astype(np.float32),
        "x2": rng.normal(size=(2, 4, 5, 5)).astype(np.float32),
    }
    for z_last in (False, True):
        model = _conv_add_relu([4, 5, 5], z_last=z_last)
        want = _run(model, feeds)
        fused = copy.deepcopy(model)
        assert fuse_for_onnxruntime(fused) == 1
        assert [n.op_type for n in fused.graph.node].count("FusedConv") == 1
        assert not {"Conv", "Relu"} & {n.op_type for n in fused.graph.node}
        assert _topological(fused)  # z computed after the Conv: the fused node sits where the ReLU was
        np.testing.assert_allclose(_run(fused, feeds), want, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("case", ["broadcast_z", "conv_read_twice"])
def test_conv_add_relu_left_alone_where_fusing_would_change_it(case: str) -> None:
    rng = np.random.default_rng(2)
    z_shape = [4, 5, 1] if case == "broadcast_z" else [4, 5, 5]
    model = _conv_add_relu(z_shape, extra_reader=case == "conv_read_twice")
    feeds = {
        "x": rng.normal(size=(2, 3, 5, 5)).astype(np.float32),
        "x2": rng.normal(size=(2, *z_shape)).astype(np.float32),
    }
    want = _run(model, feeds)
    kept = copy.deepcopy(model)
    assert fuse_for_onnxruntime(kept) == 0
    assert kept.SerializeToString() == model.SerializeToString()
    np.testing.assert_array_equal(_run(kept, feeds), want)


def _softplus(threshold: float, beta: float) -> onnx.ModelProto:
    """torch's ``softplus(x, beta, threshold)`` as its exporter writes it."""
    nodes = []
    y = "x"
    if beta != 1.0:
        nodes.append(helper.make_node("Mul", ["x", "beta"], ["xb"]))
        y = "xb"
    nodes += [
        helper.make_node("Greater", [y, "threshold"], ["above"]),
        helper.make_node("Softplus", [y], ["soft"]),
    ]
    if beta != 1.0:
        nodes.append(helper.make_node("Div", ["soft", "beta"], ["scaled"]))
    nodes.append(helper.make_node("Where", ["above", "x", "scaled" if beta != 1.0 else "soft"], ["y"]))
    inits = {"threshold": np.array(threshold), **({"beta": np.array(beta)} if beta != 1.0 else {})}
    return _model(nodes, {"x": ["B"]}, inits, ["B"])


X_SOFT = np.concatenate([np.linspace(-40, 60, 20001), [0.0, -1e30, 1e30, 3e38, np.inf, -np.inf]]).astype(np.float32)


@pytest.mark.parametrize(("threshold", "beta"), [(20.0, 1.0), (20.0, 4.0), (SOFTPLUS_EXACT, 0.5)])
def test_softplus_with_an_exact_threshold_is_one_node(threshold: float, beta: float) -> None:
    model = _softplus(threshold, beta)
    fused = copy.deepcopy(model)
    assert fuse_for_onnxruntime(fused) == 1
    assert not {"Where", "Greater"} & {n.op_type for n in fused.graph.node}
    assert not any(t.name == "threshold" for t in fused.graph.initializer)
    want, got = _run(model, {"x": X_SOFT}), _run(fused, {"x": X_SOFT})
    reference = np.logaddexp(0.0, X_SOFT.astype(np.float64) * beta) / beta
    # the one documented difference: where x * beta overflows float32 the bare form gives inf
    overflow = np.abs(X_SOFT.astype(np.float64) * beta) > np.finfo(np.float32).max
    if beta > 1.0:
        big = overflow & (X_SOFT > 0) & np.isfinite(X_SOFT)
        assert np.all(np.isinf(got[big])) and np.all(np.isfinite(want[big]))
    same = ~overflow
    finite = same & np.isfinite(reference)
    np.testing.assert_array_equal(got[same & ~finite], want[same & ~finite])
    # as close to the float64 softplus as the three-node form (both: float32 rounding)
    scale = np.maximum(np.abs(reference[finite]), 1e-30)
    assert np.max(np.abs(got[finite] - reference[finite]) / scale) <= 4e-7
    assert np.max(np.abs(want[finite] - reference[finite]) / scale) <= 4e-7


@pytest.mark.parametrize(("threshold", "beta"), [(5.0, 1.0), (20.0, 3.0)])
def test_softplus_left_alone_where_the_bare_node_differs(threshold: float, beta: float) -> None:
    model = _softplus(threshold, beta)
    kept = copy.deepcopy(model)
    assert fuse_for_onnxruntime(kept) == 0
    assert kept.SerializeToString() == model.SerializeToString()
    if threshold < SOFTPLUS_EXACT:  # the rewrite would be wrong here: softplus(6) = 6.0025, not 6
        above = X_SOFT[(threshold < X_SOFT) & (X_SOFT < 8)]
        bare = np.logaddexp(0.0, above.astype(np.float64))
        assert np.max(np.abs(bare - above)) > 1e-4


def test_the_runtime_runs_the_fused_graph_and_can_be_told_not_to() -> None:
    path = shipped_models("strips")["strips16_small"]
    fused, plain = OnnxEstimator(path, threads=1).prepare(), OnnxEstimator(path, threads=1, fuse=False).prepare()
    assert fused._fused(path.read_bytes()) != path.read_bytes()
    assert plain._fused(path.read_bytes()) == path.read_bytes()
    frames = simulate_shard(fused.card_scene_, 424242, 0, 32)["readings"].astype(np.float32)
    want = plain.predict(frames)
    tolerance = 2e-6 * float(want.max() - want.min())
    np.testing.assert_allclose(fused.predict(frames), want, rtol=0, atol=tolerance)
    for i in range(4):  # the one-frame path (bound buffers) runs the same fused graph
        np.testing.assert_allclose(fused.predict(frames[i : i + 1]), want[i : i + 1], rtol=0, atol=tolerance)
