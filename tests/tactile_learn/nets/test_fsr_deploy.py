"""The FSR network's export graph (tactile_learn.nets.fsr_deploy): LeanFsrNet computes FsrNet's
function (features, normalisation and output scalings folded into the weights) on trained and random
weights, keeps its outputs in range for wild weights, and exports to the
smaller ONNX graph with the same outputs."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch", reason="torch (training extra) is not installed")

import numpy as np  # noqa: E402

from synth.scene import load_scene  # noqa: E402
from synth.sensors import fsr  # noqa: E402
from tactile_learn.nets.fsr import FsrNet, build_fsr_net, input_stats  # noqa: E402
from tactile_learn.nets.fsr_deploy import LeanFsrNet  # noqa: E402
from tactile_learn.tasks import get_task  # noqa: E402
from tests.paths import REPO_ROOT  # noqa: E402

SCENE = load_scene("fsr6")


def _readings(n: int, seed: int) -> np.ndarray:
    """fsr6 frames (contacts and none) and edge codes: 0, full scale - 1, full scale."""
    frames = fsr.make_simulator(SCENE).simulate(n, np.random.default_rng(seed))["readings"].astype(np.float32)
    full = fsr.Readout(SCENE.sensor.readout).full_scale
    edges = np.array([[0.0] * 6, [full - 1.0] * 6, [full] * 6, [0.0, 5.0, 900.0, 3.0, 400.0, 1000.0]])
    return np.concatenate([frames, edges.astype(np.float32)])


def _random_net(seed: int) -> FsrNet:
    torch.manual_seed(seed)
    stats = input_stats(_readings(500, seed), np.linspace(0.0, 8.0, 504), SCENE)
    net = build_fsr_net("small", SCENE, stats)
    with torch.no_grad():  # not a trained net: scale the outputs into the forces' and logits' ranges
        for p in net.parameters():
            p.mul_(2.0)
    return net.eval()


def _close(lean: torch.Tensor, full: torch.Tensor) -> None:
    lean_np, full_np = lean.numpy(), full.numpy()
    span = full_np.max(axis=0) - full_np.min(axis=0) + 1e-6
    assert (np.abs(lean_np - full_np) / span).max() < 1e-5


@pytest.mark.parametrize("seed", [1, 2])
def test_lean_net_equals_the_network_on_random_weights(seed: int) -> None:
    net = _random_net(seed)
    x = torch.from_numpy(_readings(2000, 10 + seed))
    with torch.inference_mode():
        full, lean = net(x), LeanFsrNet(net).eval()(x)
    assert full[:, 2].std() > 0.01 and full[:, 3].std() > 0.01  # the outputs vary: a real comparison
    _close(lean, full)


def test_lean_net_equals_the_shipped_network() -> None:
    from tactile_learn.torch_estimator import TorchEstimator

    net = TorchEstimator.from_checkpoint(REPO_ROOT / "models" / "fsr.pt").net
    x = torch.from_numpy(_readings(3000, 5))
    with torch.inference_mode():
        _close(LeanFsrNet(net).eval()(x), net(x))


def test_export_module_is_the_lean_net_and_exports_fewer_nodes(tmp_path) -> None:  # type: ignore[no-untyped-def]
    onnx = pytest.importorskip("onnx")
    ort = pytest.importorskip("onnxruntime")
    from tactile_learn.export import to_onnx

    net = _random_net(3)
    task = get_task("fsr")
    graph, names = task.export_module(net, SCENE)
    assert isinstance(graph, LeanFsrNet) and names == ["estimate"]
    x = _readings(300, 8)
    paths = {}
    for label, module in (("full", net), ("lean", graph.eval())):
        paths[label] = tmp_path / f"{label}.onnx"
        to_onnx(module, torch.from_numpy(x[:2]), paths[label], "readings", "estimate", {"task": "fsr"})
    nodes = {k: len(onnx.load(str(p)).graph.node) for k, p in paths.items()}
    assert nodes["lean"] <= nodes["full"] - 15  # 21 of 36
    outs = {k: ort.InferenceSession(str(p)).run(None, {"readings": x})[0] for k, p in paths.items()}
    _close(torch.from_numpy(outs["lean"]), torch.from_numpy(outs["full"]))


def test_lean_net_refuses_another_mlp() -> None:
    net = _random_net(4)
    net.mlp = torch.nn.Sequential(torch.nn.Linear(6, 5))
    with pytest.raises(ValueError, match="MLP"):
        LeanFsrNet(net)


def test_wild_outputs_stay_finite_and_probabilities_in_range() -> None:
    net = _random_net(5)
    with torch.no_grad():  # logits and log forces far beyond the exponent's clamp, both signs
        net.mlp[-1].weight.mul_(400.0)
        net.mlp[-1].bias.mul_(400.0)
    x = torch.from_numpy(_readings(2000, 6))
    with torch.inference_mode():
        lean, raw = LeanFsrNet(net).eval()(x), net.raw(x)
    assert torch.isfinite(lean).all()
    assert ((lean[:, 3:] >= 0) & (lean[:, 3:] <= 1)).all()
    log_force, logits = raw[:, 2], raw[:, 3:]
    assert all(m.any() for m in (log_force > 61, log_force < -31, logits > 61, logits < -61))  # clamps reached
    # the same clamp of log F to [-30, 60] as the network's
    np.testing.assert_allclose(lean[log_force > 61, 2].numpy(), np.exp(np.float32(60.0)), rtol=1e-6)
    np.testing.assert_allclose(lean[log_force < -31, 2].numpy(), np.exp(np.float32(-30.0)), rtol=1e-6)
    assert (lean[:, 3:][logits > 61] == 1.0).all()
    assert (lean[:, 3:][logits < -61] < 1e-13).all()
