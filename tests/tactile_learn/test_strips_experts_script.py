"""scripts/strips_experts.py: the experts' training data keeps the blind tests out, the training commands
validate on the scene they train on, and the routed model answers each frame with the expert its router
picked."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from synth.scene import load_scene
from synth.suite import load_suite
from tactile_learn.methods import resolve_method
from tactile_learn.suites import suite_eval_data
from tactile_learn.tasks import get_task
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_blend_tradeoff
import strips_experts
import strips_rule_guard


def _sources() -> list[tuple[str, str]]:
    return [s for members in strips_experts.CLUSTERS.values() for s in members] + strips_experts.UNCLUSTERED


def test_every_source_exists_once_and_the_blind_suites_stay_out() -> None:
    sources = _sources()
    assert len(sources) == len(set(sources))
    for source in [*sources, strips_experts.GENERAL, strips_experts.TWO_SPHERES]:
        assert strips_experts._source_scene(source).task == "strips"
    blind = {"strips16_unseen5", "strips16_ood"}
    assert not {kind for kind, _ in sources} & blind
    # nor a family of a blind suite under another suite's or a scene's name
    blind_names = {f.name for suite in blind for f in load_suite(suite).families}
    assert not {name for _, name in sources} & blind_names


def test_each_expert_trains_on_its_cluster_and_validates_on_the_first_folders_scene() -> None:
    root, runs = Path("data/x"), Path("runs")
    for name, line in zip(strips_experts.EXPERTS, strips_experts.plan(root, runs), strict=True):
        words = line.split()
        data = words[words.index("--data") + 1 : words.index("--val")]
        val = words[words.index("--val") + 1]
        expected = [str(strips_experts._folder(root, s, "train")) for s in strips_experts.CLUSTERS[name]]
        assert sorted(data[:-1]) == sorted(expected)
        assert data[-1] == str(strips_experts._folder(root, strips_experts.GENERAL, "train"))
        first = strips_experts.VALIDATION[name]
        assert data[0] == str(strips_experts._folder(root, first, "train"))
        assert val == str(strips_experts._folder(root, first, "val"))
        assert f"--out {runs / f'expert-{name}'}" in line
        assert f"--epochs {strips_experts.EPOCHS} " in line
    long = strips_experts.plan(root, runs, long=True)
    assert all(f"--epochs {strips_experts.LONG_EPOCHS} " in line and "expert-long-" in line for line in long)


def test_router_features_are_the_frames_shape_then_its_load() -> None:
    rng = np.random.default_rng(0)
    readings = (0.3 + rng.uniform(0.0, 0.5, (5, 32))).astype(np.float32)
    louder = (0.3 + 2.0 * (readings - 0.3)).astype(np.float32)
    a, b = strips_experts.features(readings), strips_experts.features(louder)
    assert a.shape == (5, 33) and a.dtype == np.float32
    np.testing.assert_allclose(a[:, :32], b[:, :32], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(b[:, 32] - a[:, 32], np.log(2.0), rtol=1e-5)
    idle = strips_experts.features(np.full((2, 32), 0.3, np.float32))
    assert np.isfinite(idle).all()


class _Constant:
    def __init__(self, value: float) -> None:
        self.value = value

    def predict(self, readings: np.ndarray) -> np.ndarray:
        return np.full((len(readings), 16, 16), self.value, np.float32)


def _router(readings: np.ndarray) -> np.ndarray:
    """Logits (as ``strips_experts.load_mlp``'s ``run``) that put the frame's first feature's choice
    first, at a probability set by the second."""
    x = strips_experts.features(readings)
    choice = x[:, 0].astype(int)
    logits = np.zeros((len(x), len(strips_experts.CHOICES)), np.float32)
    logits[np.arange(len(x)), choice] = x[:, 1]
    return logits


def test_each_frame_goes_to_the_routers_choice_only_when_it_is_sure(monkeypatch: pytest.MonkeyPatch) -> None:
    routed = strips_experts.RoutedStrips.__new__(strips_experts.RoutedStrips)
    routed.estimators = {name: _Constant(float(k)) for k, name in enumerate(strips_experts.CHOICES)}
    routed.router, routed.probability = _router, strips_experts.ROUTE_PROBABILITY
    n = len(strips_experts.CHOICES)
    choices = np.array([0, 1, 2, 3, 2, 1])
    sure = np.array([5.0, 5.0, 5.0, 5.0, 0.0, 0.5])  # 0: uniform (1/4), 0.5: ~0.35 < 0.5
    routed_features = np.zeros((6, 33), np.float32)
    routed_features[:, 0], routed_features[:, 1] = choices, sure
    monkeypatch.setattr(strips_experts, "features", lambda _readings: routed_features)
    maps = routed.predict(np.zeros((6, 32), np.float32))
    expected = np.where(sure >= 5.0, choices, 0)
    assert n == 4
    np.testing.assert_array_equal(maps[:, 0, 0], expected.astype(np.float32))


def test_the_flags_threshold_is_the_lowest_that_keeps_both_shares() -> None:
    guard = strips_rule_guard
    rng = np.random.default_rng(1)
    p = rng.uniform(0.0, 1.0, 1001)  # 1001 values: the grid of quantiles holds every one of them
    groups = rng.permutation(np.repeat([0, 1, 2], [201, 400, 400]))
    t = guard.choose_threshold(p, groups)
    assert (p[groups == 1] >= t).mean() <= guard.TWO_SPHERE_FLAG_SHARE
    assert (p[groups == 2] >= t).mean() <= guard.GENERAL_FLAG_SHARE
    lower = p[p < t].max()  # the next candidate down breaks a share
    assert (p[groups == 1] >= lower).mean() > guard.TWO_SPHERE_FLAG_SHARE or (
        p[groups == 2] >= lower
    ).mean() > guard.GENERAL_FLAG_SHARE


def test_a_losing_frame_is_one_the_rule_answers_better_by_the_margin() -> None:
    guard = strips_rule_guard
    rng = np.random.default_rng(2)
    truth = rng.uniform(0.0, 1.0, (3, 16, 16)).astype(np.float32)
    noise = rng.normal(0.0, 1.0, (3, 16, 16)).astype(np.float32)
    good, bad = truth + 0.05 * noise, truth + 3.0 * noise
    model = np.stack([good[0], bad[1], good[2]])
    rule = np.stack([bad[0], good[1], good[2]])
    assert guard.losing(model, rule, truth).tolist() == [False, True, False]


def test_the_blend_runs_from_the_model_to_the_rule() -> None:
    blend = strips_blend_tradeoff
    task = get_task("strips")
    data = next(iter(suite_eval_data(load_suite("strips16_ood"), 8, 3).values()))
    scene = load_scene("strips16")
    rule = resolve_method("strips", "intersection", scene).predict(data.inputs)
    model = resolve_method("strips", "projection", scene).predict(data.inputs)  # stands for a network
    scores = blend.blend_scores(model, rule, data, (0.0, 0.5, 1.0))
    assert scores[0] == task.metrics(model, data)["pearson_r_mean"]
    assert scores[2] == task.metrics(rule, data)["pearson_r_mean"]
    assert scores[1] not in (scores[0], scores[2])
