"""The one-press check's analytic Jacobian (``OnePressCheck.jacobian``, ``OneFrameCheck.jacobian_at``)
against central differences of the forward model, and the two paths against each other."""

from __future__ import annotations

import numpy as np
import pytest

from synth.scene import load_scene
from tactile_learn.fsr_check import OnePressCheck, one_press_check


@pytest.fixture(scope="module")
def check() -> OnePressCheck:
    return one_press_check(load_scene("fsr6")).prepare()


def _presses(n: int, seed: int, reach_mm: float = 30.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-reach_mm, reach_mm, (n, 2)), rng.uniform(-3.0, 3.0, n)])


def _central_differences(check: OnePressCheck, params: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """d conductance / d parameter (B, 6, 3) by central differences in float64 (a step far below
    the load table's cells, so it rarely straddles one of the model's kinks)."""
    columns = []
    for shift in np.eye(3) * step:
        columns.append((check.conductance(params + shift) - check.conductance(params - shift)) / (2 * step))
    return np.stack(columns, axis=2)


def _relative_error(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    """|got - want| over the largest slope of the frame (a frame's tiny slopes carry the
    differences' rounding, ~1e-10 uS / 1e-6)."""
    return np.abs(got - want) / (np.abs(want).max(axis=(1, 2), keepdims=True) + 1e-9)


def test_the_jacobian_is_the_forward_models_derivative(check: OnePressCheck) -> None:
    params = _presses(3000, seed=11)
    error = _relative_error(check.jacobian(params), _central_differences(check, params))
    # the differences' rounding (~1e-7 uS/mm on conductances of ~1000 uS) and, rarely, a kink
    # (grid node, the gate) inside the 2e-6 step: nearly all entries agree to 1e-5 (a wrong factor
    # in one term, e.g. d F / d log F twice, puts the 99th percentile at 2e-2)
    assert np.quantile(error, 0.99) < 1e-5
    assert error.max() < 1e-2


def test_the_jacobian_beyond_the_table_is_the_far_fields(check: OnePressCheck) -> None:
    params = np.array([[150.0, 20.0, 1.0], [0.0, 130.0, 0.5], [-140.0, -60.0, 2.0]])
    assert (check.conductance(params) > check.one_frame.leak).any()  # the far field still loads some disc
    jac = check.jacobian(params)
    assert np.abs(jac[..., :2]).max() > 0.0
    # (slopes of ~1e-11 uS/mm on conductances of ~1: a wider step, the far field is smooth)
    np.testing.assert_allclose(jac, _central_differences(check, params, step=1e-2), rtol=1e-4, atol=1e-14)


def test_the_jacobian_is_zero_along_the_clamps_and_finite_on_a_sensor(check: OnePressCheck) -> None:
    sensor = check._path[1][2]
    params = np.array([[sensor[0], sensor[1], 1.0], [5.0, 5.0, 7.0], [5.0, 5.0, -12.0]])
    jac = check.jacobian(params)
    assert np.isfinite(jac).all()
    assert jac[0, 2, 0] == 0.0 and jac[0, 2, 1] == 0.0  # no direction on the sensor's centre
    assert (jac[1:, :, 2] == 0.0).all()  # the force is clipped at log F = 6 and -10
    assert np.abs(jac[0, :, 2]).max() > 0.0


def test_one_frame_normal_equations_equal_the_batch_ones(check: OnePressCheck) -> None:
    """The single-frame path sums ``J^T J`` and ``J^T r`` without forming ``J``, with the model
    in the same pass: the same numbers as the batch path's Jacobian and products."""
    one = check.one_frame
    params = np.concatenate([_presses(500, seed=12), [[150.0, 20.0, 1.0], [0.0, 0.0, 6.5], [2.0, 1.0, -11.0]]])
    measured = check.conductance(params + np.array([0.7, -0.4, 0.2]))
    base = check.conductance(params)
    jac = check.jacobian(params)
    jtj = np.einsum("bsi,bsj->bij", jac, jac)
    upper = jtj[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]
    want = np.concatenate([upper, np.einsum("bsi,bs->bi", jac, measured - base)], axis=1)
    models, sums = [], []
    for (x, y, f), m in zip(params.tolist(), measured.tolist(), strict=True):
        model, normal = one.model_and_normal_equations(x, y, f, one.column(f), m)
        assert model == one.conductance(x, y, f)  # the model it sums at, bit for bit
        models.append(model)
        sums.append(normal)
    np.testing.assert_allclose(models, base, rtol=1e-13)  # (the one-frame Hertz radius: ** (1 / 3), not cbrt)
    np.testing.assert_allclose(sums, want, rtol=1e-11, atol=1e-12 * np.abs(want).max())


def test_the_refinement_reaches_a_genuine_press(check: OnePressCheck) -> None:
    """From 2 mm and 20 % off, the refinement finds a noise-free single press's conductances:
    a wrong Jacobian would stall above the threshold within the check's steps."""
    rng = np.random.default_rng(13)
    truth = np.column_stack([rng.uniform(-8.0, 8.0, (200, 2)), np.log(rng.uniform(1.0, 10.0, 200))])
    measured = check.conductance(truth)
    start = truth + np.column_stack([rng.normal(0.0, 2.0, (200, 2)), np.full(200, np.log(1.2))])
    misfit = check._refined_misfit(measured, start.copy())
    assert np.median(misfit) < 1e-3
    assert np.mean(misfit <= check.threshold) > 0.95
