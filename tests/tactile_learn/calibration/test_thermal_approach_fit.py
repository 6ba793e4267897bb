"""The approach's shared parameters (residual gap, approach speed; synth.sensors.thermal.approach)
on simulated touches of the robot sensor: curves made from the calibration's own model with known
values plus white noise; a fit of the two from elsewhere gives them back (identifiability)."""

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


def test_gap_and_speed_are_recovered() -> None:
    scene = robot_scene(**{"objects.offset_k": [-10.0, -4.0]})
    series, noise, _ = simulated_series(scene, 4, 11)
    problem = CalibrationProblem(prepare_touches(series), CLASSES, True, ("approach",))
    problem.prior_row_k = PRIOR_ROW_TOUCH_K  # weak linear priors: 1 K rows pull the drifts
    names = [p.name for p in problem.shared]
    i_gap, i_speed = names.index("approach.gap_um"), names.index("approach.speed_mm_s")
    truth = problem.start()
    truth[i_gap], truth[i_speed] = math.log(60.0), math.log(3.0)
    cols, power, _ = problem.design(truth)
    rng = np.random.default_rng(3)
    for i in range(problem.n):
        obj_c = 5.0 + 3.0 * i  # objects 17-25 K below the heated channel: the gap carries heat
        for c, (r0, drift) in enumerate(((29.5, 0.05), (22.0, -0.02))):
            curve = r0 * cols[c, i, :, 0] + drift * cols[c, i, :, 1] + obj_c * cols[c, i, :, 2]
            if c == 0:
                curve = curve + 30.0 * power[i]  # the shared ambient's column
            sigma = noise[("heated", "passive")[c]]["white_k"]
            problem.x[c, i] = np.where(problem.mask[i], curve + rng.normal(0.0, sigma, curve.shape), 0.0)

    def residuals(theta: np.ndarray) -> np.ndarray:
        x = truth.copy()
        x[i_gap], x[i_speed] = theta
        return problem.residuals(x)

    start = np.array([math.log(400.0), math.log(0.7)])
    # the start is far off: the approach changes the curves by several mK there
    off, _, _ = problem.solve(np.r_[truth[:i_gap], start, truth[i_speed + 1 :]])
    assert np.sqrt(np.mean(off[0][problem.mask] ** 2)) > 5 * noise["heated"]["white_k"]
    fit = optimize.least_squares(
        residuals,
        start,
        bounds=([math.log(1.0), math.log(0.1)], [math.log(3000.0), math.log(50.0)]),
        x_scale="jac",
        diff_step=1e-5,
    )
    gap, speed = np.exp(fit.x)
    assert abs(gap / 60.0 - 1) < 0.1 and abs(speed / 3.0 - 1) < 0.1, (gap, speed)
    res, _, _ = problem.solve(np.r_[truth[:i_gap], fit.x, truth[i_speed + 1 :]])
    for c, ch in enumerate(("heated", "passive")):
        assert np.sqrt(np.mean(res[c][problem.mask] ** 2)) < 1.5 * noise[ch]["white_k"]


def test_the_approach_adds_two_shared_parameters_and_no_column() -> None:
    plain, more = problems_without_and_with("approach", CLASSES)
    assert [p.name for p in more.shared][-2:] == ["approach.gap_um", "approach.speed_mm_s"]
    assert more.n_free == plain.n_free + 2 and more.nuisance_columns == plain.nuisance_columns == []
    # the approach only adds to the object's column: with a negligible gap exchange the curves agree
    x = more.start()
    x[-2] = math.log(3000.0)  # a 3 mm residual gap passes ~10 W/(m^2 K) at most...
    x[-1] = math.log(50.0)  # ...for the few ms before the contact
    a, b = plain.design(plain.start())[0], more.design(x)[0]
    assert np.max(np.abs(a - b)) < 2e-3 * np.max(np.abs(a))
