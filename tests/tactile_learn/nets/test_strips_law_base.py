"""The general strip network's classical base (sizes ``*_law``): the network starts from the
classical intersection estimate itself, and its deployed (exported) form computes the same map."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed: nothing here runs without it")

import torch

from synth.dataset import simulate_shard
from synth.errors import ModelError
from synth.scene import load_scene
from synth.sensors.strips import StripSensor
from tactile_learn.estimators.classical.intersection import IntersectionEstimator
from tactile_learn.nets.strips import build_strip_net, input_stats
from tactile_learn.nets.strips_deploy import deploy
from tactile_learn.nets.strips_general import MAX_SHARE, GeneralStripNet, law_inverse
from tactile_learn.runtime import OnnxEstimator


@pytest.fixture(scope="module")
def frames() -> dict[str, np.ndarray]:
    return simulate_shard(load_scene("strips5"), 11, 0, 200)


def _net(frames: dict[str, np.ndarray], size: str) -> GeneralStripNet:
    scene = load_scene("strips5")
    stats = input_stats(frames["readings"], frames["pressure"], scene)
    torch.manual_seed(0)
    net = build_strip_net(size, scene, stats)
    assert isinstance(net, GeneralStripNet)
    return net.eval()


def test_the_law_inverse_is_the_sensors_and_clamped_where_it_diverges() -> None:
    scene = load_scene("strips5")
    law = StripSensor(scene.sensor).law
    share = np.linspace(0.0, 0.99, 100)
    p0, n = float(scene.sensor.piezo.p0_kpa), float(scene.sensor.piezo.exponent)
    for exponent in (n, 1.6):  # the scenes' exponent (1: no power node) and the general formula
        law.exponent = exponent
        got = law_inverse(torch.from_numpy(share), p0, exponent).numpy()
        want = law.stress_from_gain(np.minimum(share, MAX_SHARE))
        np.testing.assert_allclose(got, want, rtol=1e-9)
        assert np.all(np.isfinite(got)) and got[-1] == got[share >= MAX_SHARE][0]


def test_new_networks_start_from_the_classical_estimate(frames: dict[str, np.ndarray]) -> None:
    """With the head at zero (as built) the law base answers what the intersection rule answers;
    the linear base of the models trained before does not, where crossings carry large shares."""
    readings = frames["readings"].astype(np.float32)
    classical = IntersectionEstimator(load_scene("strips5"), noise_floor=0.0).prepare().predict(readings)
    with torch.inference_mode():
        law = _net(frames, "small_law")(torch.from_numpy(readings)).numpy()
        linear = _net(frames, "small")(torch.from_numpy(readings)).numpy()
    loaded = classical.reshape(len(classical), -1).max(axis=1) > 1.0
    # equal up to the built head's small positive mass (softplus of its -1 bias) and the noise-level
    # floor on the network's frame total, which the law's slope 1 / (1 - share)^2 amplifies ~10x at
    # the largest crossing share (0.7); the linear base misses that crossing by a factor of three
    law_error = np.abs(law - classical)[loaded].max() / classical[loaded].max()
    linear_error = np.abs(linear - classical)[loaded].max() / classical[loaded].max()
    assert law_error < 0.1 and linear_error > 0.5
    assert np.median(np.abs(law - classical)[loaded]) < 0.01 * classical[loaded].max()


@pytest.mark.parametrize("size", ["small_law", "small", "tiny_law"])
def test_the_deployed_form_computes_the_trained_map(frames: dict[str, np.ndarray], size: str) -> None:
    net = _net(frames, size)
    with torch.no_grad():  # a trained-looking head: the base map's rescaling matters everywhere
        for p in net.head.parameters():
            p.normal_(0.0, 0.3)
    probe = torch.from_numpy(frames["readings"][:64].astype(np.float32))
    deployed = deploy(net, load_scene("strips5"), probe)  # refuses a difference (ModelError)
    with torch.inference_mode():
        np.testing.assert_allclose(deployed(probe)[0].numpy(), net(probe).numpy(), rtol=1e-4, atol=1e-3)


def test_the_card_chooses_onnxruntimes_optimisation_level(tmp_path: Path) -> None:
    source = Path("models/strips16.onnx")
    card = json.loads(source.with_suffix(".json").read_text())
    assert card["graph_optimization"] == "extended"
    readings = simulate_shard(load_scene("strips16"), 3, 0, 8)["readings"]
    path = tmp_path / "m.onnx"
    shutil.copy(source, path)
    maps = {}
    for level in ("basic", "all"):
        path.with_suffix(".json").write_text(json.dumps({**card, "graph_optimization": level}))
        maps[level] = OnnxEstimator(path, route=False).prepare().predict(readings)  # (its members stay behind)
    np.testing.assert_allclose(maps["basic"], maps["all"], rtol=1e-4, atol=1e-3)
    path.with_suffix(".json").write_text(json.dumps({**card, "graph_optimization": "fastest"}))
    with pytest.raises(ModelError, match="graph_optimization 'fastest'"):
        OnnxEstimator(path, route=False).prepare().predict(readings)
