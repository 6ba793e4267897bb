"""The thermal fits at batch 1: the same answers as the batch path, and as the least-squares
solutions they replace (calibrated fit: projections factorised once; physics fit: one model call
per Levenberg-Marquardt iteration, and a one-curve path at batch 1)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from synth.errors import InputError
from synth.scene import Scene, load_scene
from synth.sensors.thermal import make_simulator
from tactile_learn.estimators.classical.calibrated_fit import MODEL_ERROR_K, STEP_S, CalibratedFitEstimator
from tactile_learn.estimators.classical.curve_match import NONE_BONUS, softmax
from tactile_learn.estimators.classical.physics_fit import _BOUNDS, PhysicsFitEstimator, _drop_fast, contact_drop
from tactile_learn.tasks.thermal import ThermalTask
from tests.tactile_learn.test_thermal_real import robot_scene

TASK = ThermalTask()


def held_out_curves(scene: Scene, n: int, seed: int) -> np.ndarray:
    """Inputs of ``n`` touches of ``scene`` as the task gives them to an estimator."""
    data = make_simulator(scene).simulate(n, np.random.default_rng(seed))
    return np.asarray(TASK.example_inputs(data, scene), dtype=np.float32)


def lstsq_scores(est: CalibratedFitEstimator, x: np.ndarray) -> np.ndarray:
    """The calibrated fit's probabilities by a least-squares solve per (contact start, template):
    the computation the prepared projections replace."""
    cfg: Any = est.scene.sensor
    x = np.asarray(x, dtype=np.float64)
    x = x[:, None, :] if x.ndim == 2 else x
    b, n_ch, w = x.shape
    basis, owner = est.templates_
    heater_off = cfg.sensor.heater in ("off", "step")
    n_lin = 2 * n_ch + 1 + (1 if heater_off else 0)
    y = x.reshape(b, n_ch * w).T
    best = np.full((b, len(cfg.class_names)), np.inf)
    step = max(1, round(STEP_S * cfg.readout.sampling_hz))
    for start in range(-w // 3, w - step, step):
        rel = np.arange(w) - start + w
        for m in range(len(basis)):
            a = np.zeros((n_ch * w, n_lin))
            for c in range(n_ch):
                rows = slice(c * w, (c + 1) * w)
                a[rows, 2 * c], a[rows, 2 * c + 1] = basis[m][c, rel, 0], basis[m][c, rel, 1]
                a[rows, 2 * n_ch] = basis[m][c, rel, 2]
                if heater_off:
                    a[rows, -1] = basis[m][c, rel, 3]
            coef = np.linalg.lstsq(a, y, rcond=None)[0]
            best[:, owner[m]] = np.minimum(best[:, owner[m]], ((a @ coef - y) ** 2).sum(axis=0))
    line = np.zeros((n_ch * w, 2 * n_ch))
    for c in range(n_ch):
        line[c * w : (c + 1) * w, 2 * c] = 1.0
        line[c * w : (c + 1) * w, 2 * c + 1] = np.arange(w) / cfg.readout.sampling_hz
    none = ((line @ np.linalg.lstsq(line, y, rcond=None)[0] - y) ** 2).sum(axis=0)
    sigma = max(cfg.readout.noise_k, MODEL_ERROR_K)
    scores = np.concatenate([-best, -none[:, None]], axis=1) / (2 * sigma**2)
    scores[:, -1] += NONE_BONUS
    return softmax(scores)


@pytest.mark.parametrize("scene_name", ["thermal", "robot"])
def test_calibrated_fit_projections_match_least_squares_at_every_batch_size(scene_name: str) -> None:
    scene = robot_scene() if scene_name == "robot" else load_scene(scene_name)
    est = CalibratedFitEstimator(scene, chunk=5).prepare()  # type: ignore[arg-type]
    x = held_out_curves(scene, 3, seed=41)[:12]  # type: ignore[arg-type]
    batch = est.predict_proba(x)
    # probabilities within float32 rounding of the solved least squares (the projections'
    # |y|^2 - |Q^T y|^2 cancels to ~1e-7 of the scores' unit)
    np.testing.assert_allclose(batch, lstsq_scores(est, x), atol=2e-6)
    singles = np.concatenate([est.predict_proba(x[i : i + 1]) for i in range(len(x))])
    np.testing.assert_allclose(singles, batch, atol=1e-6)


def test_calibrated_fit_refuses_bad_input_at_batch_1() -> None:
    scene = load_scene("thermal")
    est = CalibratedFitEstimator(scene).prepare()
    x = held_out_curves(scene, 1, seed=5)[:1]
    x[0, 7] = np.nan
    with pytest.raises(InputError, match=r"finite|NaN"):
        est.predict_proba(x)


def test_physics_fit_model_is_contact_drop_to_the_bit() -> None:
    """The fit's own model evaluation (no checks, the series only where it is kept) gives
    contact_drop's numbers over the fit's parameter box, before and after the onset."""
    rng = np.random.default_rng(12)
    n = 200
    t_rel = np.arange(125)[None, :] / 50.0 - rng.uniform(-0.2, 2.4, (n, 1))
    args = (
        rng.uniform(200.0, 5000.0, n),  # C
        rng.uniform(0.0, 400.0, n),  # G
        np.exp(rng.uniform(*_BOUNDS[2], n)),  # e
        np.exp(rng.uniform(*_BOUNDS[3], n)),  # H
        np.exp(rng.uniform(*_BOUNDS[4], n)),  # k_s
    )
    fast = _drop_fast(t_rel, *args)
    assert np.array_equal(fast, contact_drop(t_rel, *args))
    assert (fast[t_rel <= 0] == 0).all() and np.isfinite(fast).all()


def test_physics_fit_batch_1_gives_the_batch_answers() -> None:
    scene = load_scene("thermal")
    est = PhysicsFitEstimator(scene, chunk=7).prepare()
    x = held_out_curves(scene, 2, seed=23)
    batch = est.predict_proba(x)
    singles = np.concatenate([est.predict_proba(x[i : i + 1]) for i in range(len(x))])
    # batch 1 takes the one-curve path (physics_fit_one_frame): the batch's answers to rounding
    np.testing.assert_allclose(singles, batch, rtol=0, atol=1e-6)
    assert np.allclose(batch.sum(axis=1), 1.0, atol=1e-5)
    bad = x[:1].copy()
    bad[0, 3] = np.inf
    with pytest.raises(InputError, match=r"finite|NaN|inf"):
        est.predict_proba(bad)
