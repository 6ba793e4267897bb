"""The calibrated fit's projections without the constant: residuals as least squares gives them,
for designs that contain the constant (centred curves) and for designs that do not."""

from __future__ import annotations

import numpy as np
import pytest

from synth.scene import load_scene
from tactile_learn.estimators.classical.calibrated_fit import CalibratedFitEstimator, _column_bases
from tests.tactile_learn.estimators.test_thermal_fits_batch1 import held_out_curves, lstsq_scores


def residuals_by_bases(designs: np.ndarray, y: np.ndarray) -> np.ndarray:
    """RSS (B, G) of curves ``y`` (B, N) against every design by the bases of _column_bases."""
    q, n_columns, centred = _column_bases(designs)
    if centred:
        y = y - y.mean(axis=1, keepdims=True)
    proj = (y @ q).reshape(len(y), len(designs), n_columns)
    return (y * y).sum(axis=1)[:, None] - (proj**2).sum(axis=2)


def residuals_by_lstsq(designs: np.ndarray, y: np.ndarray) -> np.ndarray:
    out = np.empty((len(y), len(designs)))
    for g, a in enumerate(designs):
        coef = np.linalg.lstsq(a, y.T, rcond=None)[0]
        out[:, g] = ((a @ coef - y.T) ** 2).sum(axis=0)
    return out


@pytest.mark.parametrize("with_constant", [True, False])
def test_column_bases_give_least_squares_residuals(with_constant: bool) -> None:
    rng = np.random.default_rng(8)
    n = 60
    t = np.linspace(0.0, 1.0, n)
    designs = np.stack([np.stack([1.0 + np.exp(-k * t), t**2 + k, np.sin(k * t)], axis=1) for k in range(1, 9)])
    if with_constant:
        designs[:, :, 2] = -np.exp(-np.arange(1, 9)[:, None] * t)  # column 0 + column 2 = 1
    designs[3, :, 1] = 2.0 * designs[3, :, 0]  # a rank-deficient design
    y = 30.0 + rng.normal(size=(5, n)) + 2.0 * t
    _, n_columns, centred = _column_bases(designs)
    assert centred == with_constant and n_columns == (2 if with_constant else 3)
    np.testing.assert_allclose(residuals_by_bases(designs, y), residuals_by_lstsq(designs, y), rtol=1e-9, atol=1e-9)


def test_calibrated_fit_centres_the_thermal_scene_and_matches_least_squares_closely() -> None:
    """The seed scene's designs all hold the constant: a third fewer columns, and probabilities
    within float32 rounding of the solved least squares (the uncentred projections: 5e-7)."""
    scene = load_scene("thermal")
    est = CalibratedFitEstimator(scene).prepare()
    _, _, n_columns, centred = est.projections_
    assert centred and n_columns == 2
    x = held_out_curves(scene, 3, seed=43)
    np.testing.assert_allclose(est.predict_proba(x), lstsq_scores(est, x), rtol=0, atol=1e-7)
