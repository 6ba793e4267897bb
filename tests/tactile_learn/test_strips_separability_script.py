"""scripts/strips_separability.py: the held-out classifier tells apart what differs and not what is the same."""

from __future__ import annotations

import sys

import numpy as np

from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_separability as separability


def test_two_draws_of_one_distribution_are_not_told_apart() -> None:
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(400, 33)).astype(np.float32), rng.normal(size=(400, 33)).astype(np.float32)
    assert abs(separability.held_out_accuracy(a, b, seed=1, epochs=5) - 0.5) < 0.1


def test_shifted_distributions_are_told_apart() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(size=(400, 33)).astype(np.float32)
    b = rng.normal(size=(400, 33)).astype(np.float32)
    b[:, 3] += 3.0
    assert separability.held_out_accuracy(a, b, seed=1, epochs=5) > 0.9


def test_features_are_load_shares_and_log_total() -> None:
    readings = np.full((2, 32), 0.3, dtype=np.float32)
    readings[0, :2] += 0.1
    readings[1, 5] += 0.4
    f = separability.features(readings, 0.3)
    assert f.shape == (2, 33)
    np.testing.assert_allclose(f[:, :32].sum(axis=1), 32.0, rtol=1e-5)
    assert f[1, 32] > f[0, 32]  # totals 0.2 and 0.4 V above the unloaded level: the log orders them


def test_a_family_against_random_shapes_runs_on_a_small_draw() -> None:
    result = separability.family_against_shapes("strips16_ood", "diagonal_edge", 60, 3)
    assert result["shape_frames"] >= 30 and 0.0 <= result["held_out_accuracy"] <= 1.0
