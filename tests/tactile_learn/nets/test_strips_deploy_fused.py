"""The exported strip graphs (nets.strips_deploy, the reassociated sums of nets.strip_blocks and
nets.strips) under the load-time fusions (tactile_learn.onnx_fuse): fewer nodes, the unfused graph's
outputs to float32 rounding and the trained network's float64 outputs within the export's tolerance,
on touched, empty and saturated frames."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed: nothing here runs without it")
onnx = pytest.importorskip("onnx")
ort = pytest.importorskip("onnxruntime")

import torch  # noqa: E402

from synth.dataset import simulate_shard  # noqa: E402
from tactile_learn.export import parity_check, to_onnx  # noqa: E402
from tactile_learn.methods import shipped_models  # noqa: E402
from tactile_learn.nets.strips_general import GeneralStripNet, GeneralStripNetWithResidual  # noqa: E402
from tactile_learn.onnx_fuse import fused_model_bytes  # noqa: E402
from tactile_learn.tasks import get_task  # noqa: E402
from tactile_learn.torch_estimator import TorchEstimator  # noqa: E402


def _session(model: bytes) -> Any:
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_EXTENDED
    return ort.InferenceSession(model, sess_options=options, providers=["CPUExecutionProvider"])


def _strip_frames(scene: Any, n: int) -> np.ndarray:
    """Touched frames, empty frames (every strip at rest), and readings at and past both rails."""
    touched = simulate_shard(scene, 424242, 0, n)["readings"].astype(np.float32)
    rest = np.full_like(touched[:2], float(scene.sensor.readout.offset_v))
    supply = float(scene.sensor.readout.supply_v)
    rails = np.stack([np.full_like(touched[0], volts) for volts in (0.0, supply, 10 * supply)])
    mixed = touched[:1].copy()
    mixed[0, ::3] = supply  # a few strips saturated inside a touched frame
    return np.concatenate([touched, rest, rails, mixed])


@pytest.mark.parametrize("name", ["strips16", "strips16_small"])
def test_the_exported_strip_graph_fused_matches_float64_torch(name: str, tmp_path: Path) -> None:
    """The deployed graph as `export` writes it, fused at load: fewer nodes, the unfused graph's
    outputs to float32 rounding, and the trained network's (float64) within the export's tolerance."""
    trained = TorchEstimator.from_checkpoint(shipped_models("strips")[name].with_suffix(".pt"), threads=1)
    task = get_task("strips")
    graph, names = task.export_module(trained.net, trained.scene)
    frames = _strip_frames(trained.scene, 48)
    path = tmp_path / "m.onnx"
    to_onnx(graph.eval(), torch.from_numpy(frames[:2]), path, task.input_key, names, {"task": "strips"})
    plain = path.read_bytes()
    fused = fused_model_bytes(plain)
    before, after = onnx.load_from_string(plain), onnx.load_from_string(fused)
    blocks = len(trained.net.blocks)
    # the export's parity check covers the graph as the runtime runs it, fused
    parity = parity_check(graph, path, frames[:8])
    assert max(parity["rel_err_b1"], parity["rel_err_b7"]) <= 1e-5
    # the softplus, the first crossing features and every mixing block
    assert [n.op_type for n in after.graph.node].count("FusedConv") == blocks + 1
    assert len(after.graph.node) == len(before.graph.node) - 2 * (blocks + 1) - 2
    want = _session(plain).run(None, {"readings": frames})
    got = _session(fused).run(None, {"readings": frames})
    reference = GeneralStripNetWithResidual(copy.deepcopy(trained.net), trained.scene).double().eval()
    with torch.inference_mode():
        exact = [t.numpy() for t in reference(torch.from_numpy(frames).double())]
    for g, w, e in zip(got, want, exact, strict=True):
        span = max(float(e.max() - e.min()), 1.0)
        assert float(np.abs(g - w).max()) <= 2e-6 * span
        assert float(np.abs(g - e).max()) <= 1e-4 * span
    empty = slice(48, 50)
    # empty frames stay (near) empty, as close as float32 rounding of values of 1e-14 to 1e-5 kPa
    np.testing.assert_allclose(got[0][empty], want[0][empty], rtol=1e-5, atol=1e-9)
    assert float(np.abs(got[0][empty]).max()) < 1e-4
    assert all(np.all(np.isfinite(g)) for g in got)


def test_the_two_sphere_network_fused_matches_float64_torch(tmp_path: Path) -> None:
    """The first architecture (strips16_spheres) exports its training module: its sums reassociated
    and its beta-4 softplus give one FusedConv per mixing block and the first features, one
    Softplus; outputs as the float64 network's within the export's tolerance."""
    trained = TorchEstimator.from_checkpoint(shipped_models("strips")["strips16_spheres"].with_suffix(".pt"), threads=1)
    assert not isinstance(trained.net, GeneralStripNet)
    frames = _strip_frames(trained.scene, 48)
    path = tmp_path / "m.onnx"
    to_onnx(trained.net.eval(), torch.from_numpy(frames[:2]), path, "readings", "pressure", {"task": "strips"})
    plain = path.read_bytes()
    fused = onnx.load_from_string(fused_model_bytes(plain))
    kinds = [n.op_type for n in fused.graph.node]
    assert kinds.count("FusedConv") == len(trained.net.blocks) + 1 and "Where" not in kinds
    got = _session(fused.SerializeToString()).run(None, {"readings": frames})[0]
    want = _session(plain).run(None, {"readings": frames})[0]
    with torch.inference_mode():
        exact = copy.deepcopy(trained.net).double()(torch.from_numpy(frames).double()).numpy()
    span = float(exact.max() - exact.min())
    assert float(np.abs(got - want).max()) <= 2e-6 * span
    assert float(np.abs(got - exact).max()) <= 1e-4 * span


def test_strip_loads_are_the_sensors_readout_inverse() -> None:
    """StripLoads' six-node form against the numpy inverse (float64), rails and past them included."""
    from synth.sensors.strips import StripSensor

    trained = TorchEstimator.from_checkpoint(shipped_models("strips")["strips16_small"].with_suffix(".pt"), threads=1)
    frames = _strip_frames(trained.scene, 32).astype(np.float64)
    want = StripSensor(trained.scene.sensor).invert_readings(frames)
    loads = copy.deepcopy(trained.net.loads)
    with torch.inference_mode():
        wide = loads.double()(torch.from_numpy(frames)).numpy()
        narrow = loads.float()(torch.from_numpy(frames.astype(np.float32))).numpy()
    segments = float(trained.scene.sensor.geometry.n_cols)
    assert float(np.abs(wide - want).max()) <= 1e-12 * segments
    assert float(np.abs(narrow - want).max()) <= 4e-6 * segments
    # at rest and saturated: clamped (the divider at 1e-9 of the supply from its rail, as numpy clamps it)
    assert float(wide.min()) == 0.0 and abs(float(wide.max()) - segments) < 1e-6
