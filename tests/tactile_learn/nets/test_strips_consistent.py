"""nets/strips_consistent.py: one ISRA step through the strip forward model, in training and exported."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed: nothing here runs without it")

import torch

from synth.dataset import simulate_shard
from synth.scene import load_scene
from synth.sensors.strips import StripSensor
from tactile_learn.checkpoints import load_weights
from tactile_learn.estimators.classical.projection import ProjectionEstimator
from tactile_learn.nets.strips_consistent import RATIO_CAP, ConsistencyStep
from tactile_learn.nets.strips_general import GeneralStripNet, GeneralStripNetWithResidual, StripForward
from tactile_learn.strips_consistency import StripConsistency

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "scripts"))


@pytest.fixture(scope="module")
def frames() -> dict[str, np.ndarray]:
    """Simulated frames of the default scene (readings, true maps) and their measured loads."""
    scene = load_scene("strips16")
    arrays = simulate_shard(scene, 31, 0, 24)
    loads = StripSensor(scene.sensor).invert_readings(arrays["readings"])
    return {"readings": arrays["readings"], "pressure": arrays["pressure"], "loads": loads}


def test_the_step_is_the_projection_estimators_isra_update(frames: dict[str, np.ndarray]) -> None:
    """Against the classical estimator's own update (per-layer operators, float64 maps): the same
    ratio ``J^T L / J^T L_model`` on every cell a contact reaches."""
    scene = load_scene("strips16")
    step = ConsistencyStep(StripForward(scene))
    # a start that does not explain the loads: the true maps blurred and rescaled unevenly
    truth = frames["pressure"].astype(np.float64)
    start = 0.7 * truth + 0.3 * np.roll(truth, 1, axis=2) + 0.5
    start *= np.linspace(0.6, 1.4, 16)[None, :, None]
    with torch.inference_mode():
        got = step(torch.from_numpy(start).float(), torch.from_numpy(frames["loads"]).float()).numpy()
    projection = ProjectionEstimator(scene).prepare()
    flat = start.reshape(len(start), -1)
    model, slope = projection._loads(flat.astype(np.float32))
    numerator, denominator = projection._jt(frames["loads"], slope), projection._jt(model, slope)
    want = flat * np.minimum(numerator / denominator, RATIO_CAP)
    np.testing.assert_allclose(got.reshape(len(got), -1), want, rtol=2e-3, atol=1e-3 * want.max())
    assert not np.allclose(got, start, rtol=0.01)  # the step did move the map


def test_a_map_that_explains_its_loads_is_kept(frames: dict[str, np.ndarray]) -> None:
    scene = load_scene("strips16")
    maps = frames["pressure"].astype(np.float32)
    explained = StripConsistency(scene).model_loads(maps)  # the loads this very map produces
    with torch.inference_mode():
        got = ConsistencyStep(StripForward(scene))(torch.from_numpy(maps), torch.from_numpy(explained).float()).numpy()
    np.testing.assert_allclose(got, maps, rtol=1e-3, atol=1e-3 * float(maps.max()))


def test_the_step_brings_a_wrong_map_closer_to_its_readings(frames: dict[str, np.ndarray]) -> None:
    scene = load_scene("strips16")
    consistency = StripConsistency(scene)
    truth = frames["pressure"].astype(np.float32)
    start = (truth * np.linspace(0.3, 1.7, 16, dtype=np.float32)[None, None, :] + 1.0).astype(np.float32)
    with torch.inference_mode():
        stepped = ConsistencyStep(StripForward(scene))(
            torch.from_numpy(start), torch.from_numpy(frames["loads"]).float()
        ).numpy()
    before = consistency.residual(frames["readings"], start)["residual_sigma"]
    after = consistency.residual(frames["readings"], stepped)["residual_sigma"]
    assert np.median(after) < 0.7 * np.median(before)
    assert np.all(stepped >= 0.0) and np.isfinite(stepped).all()


def _random_wide(seed: int) -> tuple[dict[str, Any], GeneralStripNet]:
    """The shipped default's file and a size-wide network with its statistics and random weights (the
    head too, so that the map is not the classical estimate)."""
    shipped = load_weights("models/strips16.pt")
    torch.manual_seed(seed)
    wide = GeneralStripNet(load_scene("strips16"), shipped["stats"], "wide")
    with torch.no_grad():
        wide.head.weight.normal_(0.0, 0.1)
    return shipped, wide


def test_wide_weights_load_into_the_consistent_size_and_export_checked(frames: dict[str, np.ndarray]) -> None:
    """The step has no weights (its buffers are not saved); the exported form takes the same step
    and reports the residual of the map before it, as the training module does."""
    from tactile_learn.nets.strips_deploy import deploy

    scene = load_scene("strips16")
    shipped, wide = _random_wide(3)
    net = GeneralStripNet(scene, shipped["stats"], "wide_consistent")
    net.load_state_dict(wide.state_dict())  # strict
    assert set(net.state_dict()) == set(wide.state_dict())
    net.eval()
    readings = torch.from_numpy(frames["readings"])
    with torch.inference_mode():
        first, stepped = wide(readings), net(readings)
        again = net.consistency(first, net.loads(readings))
        checked = GeneralStripNetWithResidual(net, scene)(readings)
        unchecked = GeneralStripNetWithResidual(wide, scene)(readings)
    np.testing.assert_allclose(stepped.numpy(), again.numpy(), rtol=1e-5, atol=1e-5)
    assert float((stepped - first).abs().max()) > 1e-3 * float(first.abs().max())
    np.testing.assert_allclose(checked[1].numpy(), unchecked[1].numpy(), rtol=1e-5)  # the first map's residual
    assert len(net.train_outputs(readings)) == 1  # the final map alone is supervised
    deployed = deploy(net, scene, readings)  # refuses a difference from the training module
    with torch.inference_mode():
        np.testing.assert_allclose(deployed(readings)[0].numpy(), stepped.numpy(), rtol=1e-4, atol=1e-3)


def test_strips_grow_carries_wide_weights_to_the_consistent_size(tmp_path: Path) -> None:
    import strips_grow

    from tactile_learn.checkpoints import build_net, save_torch

    scene = load_scene("strips16")
    shipped, wide = _random_wide(5)
    source, out = tmp_path / "wide.pt", tmp_path / "consistent.pt"
    save_torch(
        source,
        {
            "task": "strips",
            "size": "wide",
            "scene": scene.to_dict(),
            "stats": shipped["stats"],
            "state_dict": wide.state_dict(),
        },
    )
    assert strips_grow.main([str(source), "--size", "wide_consistent", "--out", str(out)]) == 0
    grown = load_weights(out)
    assert grown["size"] == "wide_consistent"
    net = build_net(grown, scene).eval()  # strict load
    readings = torch.from_numpy(simulate_shard(scene, 8, 0, 16)["readings"])
    with torch.inference_mode():
        want = net.consistency(wide.eval()(readings), net.loads(readings))
        np.testing.assert_allclose(net(readings).numpy(), want.numpy(), rtol=1e-5, atol=1e-5)
