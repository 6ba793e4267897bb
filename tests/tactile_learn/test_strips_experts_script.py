"""scripts/strips_experts.py: the experts' training data keeps the blind tests out, the training commands
validate on the scene they train on, and the routed model answers each frame with the expert its router
picked."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from synth.suite import load_suite
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_experts


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


class _Router:
    """Logits that put the frame's first reading's choice first, at a probability set by the second."""

    def run(self, _outputs: Any, feeds: dict[str, np.ndarray]) -> list[np.ndarray]:
        x = feeds["features"]
        choice = x[:, 0].astype(int)
        logits = np.zeros((len(x), len(strips_experts.CHOICES)), np.float32)
        logits[np.arange(len(x)), choice] = x[:, 1]
        return [logits]


def test_each_frame_goes_to_the_routers_choice_only_when_it_is_sure(monkeypatch: pytest.MonkeyPatch) -> None:
    routed = strips_experts.RoutedStrips.__new__(strips_experts.RoutedStrips)
    routed.estimators = {name: _Constant(float(k)) for k, name in enumerate(strips_experts.CHOICES)}
    routed.router, routed.probability = _Router(), strips_experts.ROUTE_PROBABILITY
    routed.mean, routed.std = np.zeros(33, np.float32), np.ones(33, np.float32)
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
