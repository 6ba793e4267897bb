"""The rule-correction specialist: untrained it is the intersection rule, its loss is 1 - Pearson r,
and training on one family lifts r above the rule's on that family's frames."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed")
import torch

from synth.dataset import simulate_shard
from synth.errors import ConfigError
from synth.scene import load_scene
from synth.suite import load_suite
from tactile_learn.estimators.classical.intersection import IntersectionEstimator
from tactile_learn.nets.strips_rule_correction import RuleCorrectionNet, pearson_loss
from tactile_learn.train_rule_correction import RuleCorrectionConfig, strip_loads_f32, train_rule_correction


def _blob_frames(n: int, seed: int) -> tuple[object, dict[str, np.ndarray]]:
    scene = load_suite("strips16_ood").family("blob_field").scene
    return scene, simulate_shard(scene, seed, 0, n)


def test_untrained_specialist_is_the_intersection_rule() -> None:
    scene, frames = _blob_frames(64, 5)
    readings = frames["readings"].copy()
    readings[0] = 0.0  # an idle frame too: zero map, not NaN
    rule = IntersectionEstimator(scene).prepare().predict(readings)
    net = RuleCorrectionNet(scene, hidden=16, depth=1)
    with torch.inference_mode():
        out = net(strip_loads_f32(scene, readings)).numpy()
    assert np.isfinite(out).all()
    np.testing.assert_allclose(out, rule, rtol=2e-4, atol=1e-4 * float(rule.max()))


def test_pearson_loss_is_one_minus_the_mean_r_of_frames_with_contact() -> None:
    rng = np.random.default_rng(0)
    pred, truth = rng.random((5, 4, 4)), rng.random((5, 4, 4))
    truth[2] = 0.0  # no contact: left out
    keep = [0, 1, 3, 4]
    r = [np.corrcoef(pred[i].ravel(), truth[i].ravel())[0, 1] for i in keep]
    loss = pearson_loss(torch.from_numpy(pred), torch.from_numpy(truth))
    assert float(loss) == pytest.approx(1.0 - np.mean(r), abs=1e-9)
    assert float(pearson_loss(torch.from_numpy(pred), torch.zeros(5, 4, 4, dtype=torch.float64))) == 0.0


def test_training_on_the_family_lifts_r_above_the_rule_on_its_own_frames() -> None:
    torch.set_num_threads(1)
    scene, frames = _blob_frames(512, 11)
    data = (frames["readings"], frames["pressure"])
    config = RuleCorrectionConfig(hidden=128, depth=2, epochs=15, batch=32, lr=3e-3, seed=1)
    net, history = train_rule_correction(scene, data, data, config)
    # history[0] is the rule's own r: the specialist starts there and may only keep a better epoch
    assert max(history[1:]) > history[0] + 1e-3
    with torch.inference_mode():
        r = 1.0 - float(pearson_loss(net(strip_loads_f32(scene, data[0])), torch.from_numpy(data[1])))
    assert r == pytest.approx(max(history), abs=1e-5)


def test_bad_configurations_are_named() -> None:
    scene = load_scene("strips16")
    with pytest.raises(ConfigError, match="hidden"):
        RuleCorrectionNet(scene, hidden=0)
    frames = simulate_shard(scene, 3, 0, 8)
    data = (frames["readings"], frames["pressure"])
    with pytest.raises(ConfigError, match="fewer than one batch"):
        train_rule_correction(scene, data, data, RuleCorrectionConfig(batch=64))
    with pytest.raises(ConfigError, match="positive"):
        train_rule_correction(scene, data, data, RuleCorrectionConfig(epochs=0))
