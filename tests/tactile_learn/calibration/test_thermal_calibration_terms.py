"""The calibration's optional terms on simulated touches of the robot sensor: the noise-weighted
refinement's sample weights, and the contact precursor's amplitude, which the variable projection
must recover from curves made with a known one (identifiability at the true nonlinear parameters)."""

from __future__ import annotations

import numpy as np
import pytest

from synth.materials import get_material
from tactile_learn.calibration.thermal_parameters import PRIOR_ROW_TOUCH_K
from tactile_learn.calibration.thermal_problem import CalibrationProblem
from tactile_learn.calibration.thermal_touches import FitTouch, prepare_touches
from tests.tactile_learn.test_thermal_real import robot_scene, simulated_series

CLASSES = [[get_material("aluminium")], [get_material("oak")]]


@pytest.fixture(scope="module")
def simulated() -> tuple[list[FitTouch], dict[str, dict[str, float]]]:
    scene = robot_scene(**{"objects.offset_k": [-10.0, -4.0]})
    series, noise, _ = simulated_series(scene, 4, 11)
    return prepare_touches(series), noise


def test_noise_weights(simulated: tuple[list[FitTouch], dict[str, dict[str, float]]]) -> None:
    touches, noise = simulated
    plain = CalibrationProblem(touches, CLASSES, True)
    weighted = CalibrationProblem(touches, CLASSES, True, noise=noise)
    assert np.array_equal(plain.weight, np.ones_like(plain.weight))
    w = weighted.weight[:, weighted.mask]
    assert np.all(w > 0) and np.isclose(np.mean(w**2), 1.0)
    assert np.all(weighted.weight[:, ~weighted.mask] == 0.0)
    # a sample weighs 1 / sigma(t): the flat (pre-contact) heated samples the most, and the passive
    # channel (less noise) more than the heated one wherever both are flat
    ratio = noise["heated"]["white_k"] / noise["passive"]["white_k"]
    first = weighted.weight[:, :, 0]
    assert np.allclose(first[1] / first[0], ratio, rtol=0.2)
    # the refinement's twin: weighted, with weak priors; without noise it stays the plain problem
    twin = plain.with_touch_contact(noise)
    assert np.allclose(twin.weight, weighted.weight) and twin.prior_row_k < plain.prior_row_k
    same = plain.with_touch_contact()
    assert np.array_equal(same.weight, plain.weight) and same.prior_row_k == plain.prior_row_k
    free = plain.start()
    assert np.array_equal(plain.solve(free)[0], CalibrationProblem(touches, CLASSES, True).solve(free)[0])


@pytest.mark.parametrize("weighted", [False, True])
def test_precursor_amplitude_is_recovered(
    simulated: tuple[list[FitTouch], dict[str, dict[str, float]]], weighted: bool
) -> None:
    """Curves made from the model's own columns with known linear values (a precursor of 40 % of
    V0 on the heated channel, 20 % on the passive one) plus white noise: the fit gives them back."""
    touches, noise = simulated
    problem = CalibrationProblem(touches, CLASSES, True, ("contact_precursor",), noise if weighted else None)
    problem.prior_row_k = PRIOR_ROW_TOUCH_K  # the linear priors weak (1 K rows pull a drift of 0.05 K/s)
    free = problem.start()
    cols, power, extra = problem.design(free)
    rng = np.random.default_rng(3)
    n_ch = cols.shape[0]
    truth = []
    for i in range(problem.n):
        obj_c = 10.0 + 3.0 * i
        r0 = (29.5, 22.0)
        drift = (0.05, -0.02)
        row = []
        for c in range(n_ch):
            v0 = r0[c] - obj_c
            amp = (0.4, 0.2)[c] * v0
            curve = r0[c] * cols[c, i, :, 0] + drift[c] * cols[c, i, :, 1] + obj_c * cols[c, i, :, 2]
            column = problem.nuisance_columns.index(f"{('heated', 'passive')[c]}_precursor_k")
            curve = curve + amp * extra[c, i, :, column]
            if c == 0:
                curve = curve + 30.0 * power[i]  # the shared ambient's column
            sigma = noise[("heated", "passive")[c]]["white_k"]
            problem.x[c, i] = np.where(problem.mask[i], curve + rng.normal(0.0, sigma, curve.shape), 0.0)
            row.append(amp)
        truth.append(row)
    res, sol, ambient = problem.solve(free)
    assert abs(ambient - 30.0) < 0.05
    got = sol[:, 2 * n_ch : 2 * n_ch + 2]
    assert np.allclose(got, np.array(truth), rtol=0.05, atol=0.05), (got, truth)
    # and nothing left beyond the noise
    for c, ch in enumerate(("heated", "passive")):
        assert np.sqrt(np.mean(res[c][problem.mask] ** 2)) < 2.0 * noise[ch]["white_k"]


def test_heated_only_touches_get_one_precursor_column(
    simulated: tuple[list[FitTouch], dict[str, dict[str, float]]],
) -> None:
    touches, _ = simulated
    heated_only = [FitTouch(t.file, t.label, t.t, t.heated, None, t.onset_s) for t in touches]
    problem = CalibrationProblem(heated_only, CLASSES, True, ("contact_precursor",))
    assert problem.nuisance_columns == ["heated_precursor_k"]
    _, sol, _ = problem.solve(problem.start())
    assert sol.shape == (len(touches), 2 + 1 + 1) and np.isfinite(sol).all()
