"""The calibrated fit's batch-1 screen: float32 residuals within their proven bound, the float64
residuals wherever a class can matter, and the batch's probabilities."""

from __future__ import annotations

import numpy as np

from synth.scene import load_scene
from tactile_learn.estimators.classical.calibrated_fit import MODEL_ERROR_K, CalibratedFitEstimator
from tactile_learn.estimators.classical.calibrated_one_frame import RELEVANT, screened_residuals
from tactile_learn.estimators.classical.curve_match import NONE_BONUS
from tests.tactile_learn.estimators.test_thermal_fits_batch1 import held_out_curves


def float64_residuals(est: CalibratedFitEstimator, d: np.ndarray) -> tuple[np.ndarray, float]:
    """Each class's smallest residual and the lines' by the float64 projections (the batch path)."""
    q, class_start, n_columns, _ = est.projections_
    proj = (d @ q) ** 2
    rss = d @ d - proj.reshape(-1, n_columns).sum(axis=1)
    return np.minimum.reduceat(rss[:-1], class_start), float(rss[-1])


def test_screen_gives_float64_residuals_where_a_class_can_matter() -> None:
    scene = load_scene("thermal")
    est = CalibratedFitEstimator(scene).prepare()
    _, class_start, _, centred = est.projections_
    assert centred
    unit = 2 * max(scene.sensor.readout.noise_k, MODEL_ERROR_K) ** 2
    x = held_out_curves(scene, 4, seed=71).astype(np.float64)
    flat = np.full((1, x.shape[1]), 35.0) + 1e-3 * np.random.default_rng(2).normal(size=(1, x.shape[1]))
    exact_classes = 0
    for y in np.concatenate([x, flat]):
        d = y - y.mean()
        ours, lines = screened_residuals(d, est.one_frame_, class_start, unit, NONE_BONUS)
        ref, ref_lines = float64_residuals(est, d)
        bound = est.one_frame_.error_factor * (d @ d)
        assert abs(lines - ref_lines) <= 1e-9 * (d @ d)
        assert (np.abs(ours - ref) <= bound).all()  # every class within the proven bound
        best = max((-ref / unit).max(), -ref_lines / unit + NONE_BONUS)
        matters = -ref / unit >= best - RELEVANT
        # where a class's probability can exceed exp(-RELEVANT): the float64 residual
        np.testing.assert_allclose(ours[matters], ref[matters], rtol=1e-12, atol=1e-9 * (d @ d))
        exact_classes += int(matters.sum())
    assert exact_classes > len(x)


def test_batch_1_gives_the_batch_probabilities_on_many_curves() -> None:
    scene = load_scene("thermal_wns")
    est = CalibratedFitEstimator(scene).prepare()
    x = held_out_curves(scene, 6, seed=72)
    batch = est.predict_proba(x)
    singles = np.concatenate([est.predict_proba(x[i : i + 1]) for i in range(len(x))])
    np.testing.assert_allclose(singles, batch, rtol=0, atol=1e-7)
    assert (singles.argmax(axis=1) == batch.argmax(axis=1)).all()


def test_long_windows_take_the_float64_product() -> None:
    """The robot's 2 x 600-sample windows: the screen's bound would admit hundreds of designs."""
    from tests.tactile_learn.test_thermal_real import robot_scene

    scene = robot_scene()
    est = CalibratedFitEstimator(scene).prepare()  # type: ignore[arg-type]
    assert est.one_frame_ is None
    x = held_out_curves(scene, 1, seed=73)[:4]  # type: ignore[arg-type]
    singles = np.concatenate([est.predict_proba(x[i : i + 1]) for i in range(len(x))])
    np.testing.assert_allclose(singles, est.predict_proba(x), rtol=0, atol=1e-7)
