"""The reading-side drift the contact ends (``nuisance=("drift_ends",)``; the closed form in
synth.sensors.thermal.readout) on simulated touches of the robot sensor: curves from the
calibration's own model with known values plus white noise. A fit gives the end lag back where the
drift is there, and finds no drift where there is none (identifiability)."""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize

from synth.materials import get_material
from tactile_learn.calibration.thermal_parameters import PRIOR_ROW_TOUCH_K
from tactile_learn.calibration.thermal_problem import CalibrationProblem
from tactile_learn.calibration.thermal_touches import prepare_touches
from tests.tactile_learn.test_thermal_real import problems_without_and_with, robot_scene, simulated_series

CLASSES = [[get_material("aluminium")], [get_material("oak")]]


def _simulated(
    drift_k_s: float, tau_s: float
) -> tuple[CalibrationProblem, np.ndarray, int, dict[str, dict[str, float]]]:
    scene = robot_scene(**{"objects.offset_k": [-10.0, -4.0]})
    series, noise, _ = simulated_series(scene, 4, 17)
    problem = CalibrationProblem(prepare_touches(series), CLASSES, True, ("drift_ends",))
    problem.prior_row_k = PRIOR_ROW_TOUCH_K  # weak linear priors: 1 K rows pull the drifts
    i_tau = [p.name for p in problem.shared].index("heated.drift_end_s")
    truth = problem.start()
    truth[i_tau] = math.log(tau_s)
    cols, power, _ = problem.design(truth)
    rng = np.random.default_rng(5)
    for i in range(problem.n):
        obj_c = 5.0 + 3.0 * i
        for c, (r0, drift) in enumerate(((29.5, drift_k_s), (22.0, -0.02))):
            curve = r0 * cols[c, i, :, 0] + drift * cols[c, i, :, 1] + obj_c * cols[c, i, :, 2]
            if c == 0:
                curve = curve + 30.0 * power[i]  # the shared ambient's column
            sigma = noise[("heated", "passive")[c]]["white_k"]
            problem.x[c, i] = np.where(problem.mask[i], curve + rng.normal(0.0, sigma, curve.shape), 0.0)
    return problem, truth, i_tau, noise


def _fit_lag(problem: CalibrationProblem, truth: np.ndarray, i_tau: int, start_s: float) -> tuple[float, np.ndarray]:
    def residuals(theta: np.ndarray) -> np.ndarray:
        x = truth.copy()
        x[i_tau] = theta[0]
        return problem.residuals(x)

    fit = optimize.least_squares(
        residuals,
        [math.log(start_s)],
        bounds=([math.log(0.01)], [math.log(5.0)]),
        x_scale="jac",
        diff_step=1e-5,
    )
    x = truth.copy()
    x[i_tau] = fit.x[0]
    return math.exp(float(fit.x[0])), x


def test_the_drift_end_lag_is_recovered() -> None:
    problem, truth, i_tau, noise = _simulated(0.12, 0.25)
    # from a lag 3 times too long the curves are off by many noise sigma
    x_off = truth.copy()
    x_off[i_tau] = math.log(0.8)
    off, _, _ = problem.solve(x_off)
    assert np.sqrt(np.mean(off[0][problem.mask] ** 2)) > 5 * noise["heated"]["white_k"]
    tau, x = _fit_lag(problem, truth, i_tau, 0.8)  # (from 2 s it slides to a far local minimum at ~5 s)
    assert abs(tau / 0.25 - 1) < 0.1, tau
    res, sol, _ = problem.solve(x)
    assert np.sqrt(np.mean(res[0][problem.mask] ** 2)) < 1.5 * noise["heated"]["white_k"]
    np.testing.assert_allclose(sol[:, 1], 0.12, atol=0.01)  # the heated drifts


def test_no_drift_is_found_where_there_is_none() -> None:
    problem, truth, i_tau, noise = _simulated(0.0, 0.25)
    _, x = _fit_lag(problem, truth, i_tau, 1.0)
    res, sol, _ = problem.solve(x)
    assert np.max(np.abs(sol[:, 1])) < 0.01, sol[:, 1]  # K/s: none invented
    assert np.sqrt(np.mean(res[0][problem.mask] ** 2)) < 1.5 * noise["heated"]["white_k"]


def test_drift_ends_adds_one_shared_lag_and_no_heating() -> None:
    plain, more = problems_without_and_with("drift_ends", CLASSES)
    assert [p.name for p in more.shared][-1] == "heated.drift_end_s" and more.n_free == plain.n_free + 1
    a, b = plain.design(plain.start())[0], more.design(more.start())[0]
    # only the heated drift's column changes: the rest of the design is the same
    np.testing.assert_array_equal(a[1], b[1])
    np.testing.assert_array_equal(a[0, :, :, [0, 2]], b[0, :, :, [0, 2]])
    t_rel = more.t - (more.onset - more.unpack(more.start())[1])[:, None]
    before = t_rel < 0
    np.testing.assert_allclose(b[0, :, :, 1][before], t_rel[before])  # the plain ramp before the contact
