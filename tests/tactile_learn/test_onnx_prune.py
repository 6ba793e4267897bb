"""predict runs a model's graph cut down to its first output (tactile_learn.onnx_prune): fewer
nodes, the same first output bit for bit, the whole graph where it cannot be cut."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from tactile_learn.bench import _bench_data
from tactile_learn.methods import shipped_models
from tactile_learn.onnx_prune import first_output_graph
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.tasks import get_task

onnx = pytest.importorskip("onnx")
ort = pytest.importorskip("onnxruntime")


def _frames(model: OnnxEstimator, n: int) -> np.ndarray:
    frames = get_task(model.task_name).latency_inputs(_bench_data(model.task_name, model.card_scene_, n, None))
    return np.ascontiguousarray(frames[:n], dtype=np.float32)


@pytest.mark.parametrize("name", ["strips16", "strips16_small"])
def test_the_cut_graph_gives_the_first_output_bit_for_bit(name: str) -> None:
    path = shipped_models("strips")[name]
    pruned = first_output_graph(path)
    assert pruned is not None
    whole, cut = onnx.load(str(path)), onnx.load_from_string(pruned)
    assert [o.name for o in cut.graph.output] == [whole.graph.output[0].name]
    # the check outputs' own nodes are gone (the residual's norm, the balance's absolute value); how
    # many others go with them depends on the model (strips16's consistency step shares its forward model)
    assert len(cut.graph.node) < len(whole.graph.node)
    assert {"ReduceL2", "Abs"} <= {n.op_type for n in whole.graph.node}
    assert not {"ReduceL2", "Abs"} & {n.op_type for n in cut.graph.node}
    assert cut.metadata_props == whole.metadata_props
    model = OnnxEstimator(path, threads=1, route=False).prepare()  # this graph on every frame
    assert model.first_output_session_ is not model.session_
    frames = _frames(model, 64)
    first = model.card_["outputs"][0]["name"]
    for batch in (frames[:1], frames[1:2], frames):
        want = model.session_.run([first], {"readings": batch})[0]
        np.testing.assert_array_equal(model.first_output_session_.run(None, {"readings": batch})[0], want)
        np.testing.assert_array_equal(model.predict(batch), want)
    # predict_all still runs the whole graph: every output
    assert set(model.predict_all(frames[:3])) == {o["name"] for o in model.card_["outputs"]}


def test_a_graph_of_one_output_is_run_as_it_is() -> None:
    path = shipped_models("fsr")["fsr"]
    assert first_output_graph(path) is None
    model = OnnxEstimator(path, threads=1).prepare()
    assert model.first_output_session_ is model.session_


def test_without_onnx_the_whole_graph_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    path = shipped_models("strips")["strips16_small"]
    # without onnx nothing is fused either (tactile_learn.onnx_fuse): compared with the unfused cut graph
    cut = OnnxEstimator(path, threads=1, fuse=False).prepare()
    monkeypatch.setitem(sys.modules, "onnx", None)  # import onnx raises ImportError
    assert first_output_graph(path) is None
    whole = OnnxEstimator(path, threads=1).prepare()
    assert whole.first_output_session_ is whole.session_
    frames = _frames(whole, 8)
    np.testing.assert_array_equal(whole.predict(frames), cut.predict(frames))
    np.testing.assert_array_equal(whole.predict(frames[:1]), cut.predict(frames[:1]))


def _two_output_graph(tmp_path: Path, with_subgraph: bool) -> Path:
    helper, tensor = onnx.helper, onnx.TensorProto
    x = helper.make_tensor_value_info("x", tensor.FLOAT, ["batch", 3])
    outputs = [helper.make_tensor_value_info(n, tensor.FLOAT, ["batch", 3]) for n in ("a", "b")]
    nodes = [helper.make_node("Relu", ["x"], ["a"]), helper.make_node("Neg", ["x"], ["b"])]
    if with_subgraph:  # b from an If whose branches read x from the outer scope
        branch = [helper.make_tensor_value_info("y", tensor.FLOAT, ["batch", 3])]
        then = helper.make_graph([helper.make_node("Neg", ["x"], ["y"])], "then", [], branch)
        other = helper.make_graph([helper.make_node("Identity", ["x"], ["y"])], "else", [], branch)
        flag = helper.make_tensor("flag", tensor.BOOL, [], [True])
        nodes[1] = helper.make_node("If", ["flag"], ["b"], then_branch=then, else_branch=other)
        graph = helper.make_graph(nodes, "g", [x], outputs, [flag])
    else:
        graph = helper.make_graph(nodes, "g", [x], outputs)
    path = tmp_path / f"two{int(with_subgraph)}.onnx"
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)]), str(path))
    return path


def test_a_small_graph_is_cut_and_a_subgraph_left_whole(tmp_path: Path) -> None:
    plain = first_output_graph(_two_output_graph(tmp_path, with_subgraph=False))
    assert plain is not None
    cut = onnx.load_from_string(plain)
    assert [n.op_type for n in cut.graph.node] == ["Relu"] and [o.name for o in cut.graph.output] == ["a"]
    x = np.array([[-1.0, 0.5, 2.0]], dtype=np.float32)
    np.testing.assert_array_equal(ort.InferenceSession(plain).run(None, {"x": x})[0], np.maximum(x, 0.0))
    assert first_output_graph(_two_output_graph(tmp_path, with_subgraph=True)) is None
