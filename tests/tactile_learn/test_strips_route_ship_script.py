"""scripts/strips_route_ship.py: a routed card built from a library model, a generic model and an exported
router routes each frame as the router's own ONNX graph decides, and leaves both graphs byte for byte."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.scene import load_scene
from tactile_learn.prior_route import route_features
from tactile_learn.runtime import OnnxEstimator
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_route_ship as ship

onnx = pytest.importorskip("onnx")
MODELS = REPO_ROOT / "models"


def exported_router(folder: Path, rng: np.random.Generator) -> tuple[dict[str, np.ndarray], Path]:
    """A router as strips_prior_router exports it: three Gemm layers (transB), ReLUs, and its card."""
    from onnx import TensorProto, helper, numpy_helper

    shapes = {"0": (12, 33), "2": (12, 12), "4": (1, 12)}
    weights = {k: rng.normal(0, 0.4, s).astype(np.float32) for k, s in shapes.items()}
    biases = {k: rng.normal(0, 0.1, s[0]).astype(np.float32) for k, s in shapes.items()}
    nodes, inputs = [], "features"
    for i, k in enumerate(("0", "2", "4")):
        out = "logit" if k == "4" else f"g{k}"
        nodes.append(helper.make_node("Gemm", [inputs, f"{k}.weight", f"{k}.bias"], [out], transB=1))
        if k != "4":
            nodes.append(helper.make_node("Relu", [out], [f"r{i}"]))
            inputs = f"r{i}"
    inits = [numpy_helper.from_array(weights[k], f"{k}.weight") for k in shapes]
    inits += [numpy_helper.from_array(biases[k], f"{k}.bias") for k in shapes]
    graph = helper.make_graph(
        nodes,
        "router",
        [helper.make_tensor_value_info("features", TensorProto.FLOAT, ["b", 33])],
        [helper.make_tensor_value_info("logit", TensorProto.FLOAT, ["b", 1])],
        inits,
    )
    folder.mkdir()
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)]), folder / "router.onnx")
    card = {"mean": rng.normal(0.5, 0.2, 33).tolist(), "std": rng.uniform(0.5, 2.0, 33).tolist(), "threshold": 0.5}
    (folder / "router.json").write_text(json.dumps(card))
    return card, folder


def test_the_built_card_routes_as_the_exported_router_decides(tmp_path: Path) -> None:
    import onnxruntime as ort

    card, router = exported_router(tmp_path / "router", np.random.default_rng(3))
    path = ship.build(MODELS / "strips16.onnx", MODELS / "strips16_small.onnx", None, router, tmp_path / "out", "s16")
    assert (tmp_path / "out" / "s16.onnx").read_bytes() == (MODELS / "strips16.onnx").read_bytes()
    assert (tmp_path / "out" / "s16_generic.onnx").read_bytes() == (MODELS / "strips16_small.onnx").read_bytes()
    routed = OnnxEstimator(path).prepare()
    readings = np.asarray(simulate_shard(load_scene("strips16_mixed"), 9, 0, 300)["readings"], dtype=np.float32)
    features = (route_features(readings, ship.OFFSET, ship.SHARE_SCALE) - np.float32(card["mean"])) / np.float32(
        card["std"]
    )
    session = ort.InferenceSession(str(router / "router.onnx"), providers=["CPUExecutionProvider"])
    logit = session.run(None, {"features": features.astype(np.float32)})[0][:, 0]
    clear = np.abs(logit) > 1e-3  # (the folded router rounds otherwise within ~1e-5)
    generic = routed.route_[0].generic(readings)
    assert 0.05 < generic.mean() < 0.95
    assert np.array_equal(generic[clear], (logit >= 0)[clear])
    built = json.loads(path.with_suffix(".json").read_text())["route"]
    assert built["generic_model"] == "s16_generic.onnx" and built["threshold"] == 0.5


def test_latency_reports_both_medians_and_the_routed_share(tmp_path: Path) -> None:
    _, router = exported_router(tmp_path / "router", np.random.default_rng(4))
    path = ship.build(MODELS / "strips16.onnx", MODELS / "strips16_small.onnx", None, router, tmp_path / "out", "s16")
    from synth.dataset import generate

    generate(load_scene("strips16_mixed"), 40, 5, tmp_path / "frames")
    result = ship.latency(path, MODELS / "strips16.onnx", tmp_path / "frames", frames=8, rounds=3)
    assert result["frames"] == 8 and 0.0 <= result["generic_share"] <= 1.0
    assert result["library_b1_median_us"] > 0 and result["routed_b1_median_us"] > 0


def test_check_compares_with_the_script_routing_the_same_members(tmp_path: Path) -> None:
    from synth.dataset import generate

    _, router = exported_router(tmp_path / "router", np.random.default_rng(5))
    path = ship.build(MODELS / "strips16.onnx", MODELS / "strips16_small.onnx", None, router, tmp_path / "out", "s16")
    generate(load_scene("strips16_mixed"), 60, 6, tmp_path / "frames")
    members = {"library": str(MODELS / "strips16.onnx"), "generic": str(MODELS / "strips16_small.onnx")}
    result = ship.check(path, router, tmp_path / "frames", members)
    assert result["frames"] == 60 and result["routed_differently"] <= 1  # (a logit within rounding of 0)
    assert 0.0 < result["generic_share"] < 1.0
    assert result["max_abs_diff_single_vs_batch"] < 1e-2
    if result["routed_differently"] == 0:
        assert result["max_abs_diff_vs_script"] < 1e-3
    # the same routing with another generic member is not the routed model: the comparison can fail
    other = {"library": members["library"], "generic": str(MODELS / "strips16_spheres.onnx")}
    assert ship.check(path, router, tmp_path / "frames", other)["max_abs_diff_vs_script"] > 10 * max(
        result["max_abs_diff_vs_script"], 1e-3
    )
