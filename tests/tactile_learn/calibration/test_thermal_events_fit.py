"""Contact events in the calibration (nuisance "contact_events") on simulated touches of the robot
sensor: curves made from the calibration's own model with known steps of the contact conductance
plus white noise. The events are placed at the steps and on no touch without one; a fit from the
placement gives the factors back; any other event placed stays at no step."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from scipy import optimize

from synth.materials import get_material
from tactile_learn.calibration.thermal_events import place_events
from tactile_learn.calibration.thermal_parameters import PRIOR_ROW_TOUCH_K
from tactile_learn.calibration.thermal_problem import CalibrationProblem
from tactile_learn.calibration.thermal_touches import FIT_HZ, prepare_touches
from tests.tactile_learn.test_thermal_real import robot_scene, simulated_series

CLASSES = [[get_material("aluminium")], [get_material("oak")]]
#: (touch, time after the onset, heated factor, passive factor); touch 2's slot has no true step
EVENTS = [(0, 2.5, 1.3, 0.8), (1, 3.2, 0.75, 1.25), (2, 2.0, 1.0, 1.0)]


@pytest.fixture(scope="module")
def simulated() -> tuple[CalibrationProblem, np.ndarray, dict[str, dict[str, float]]]:
    scene = robot_scene(**{"objects.offset_k": [-10.0, -4.0]})
    series, noise, _ = simulated_series(scene, 4, 11)
    problem = CalibrationProblem(prepare_touches(series), CLASSES, True, ("contact_events",))
    times = [[t for i_, t, *_ in EVENTS if i_ == i] for i in range(problem.n)]
    problem = problem.with_events(times).with_touch_contact()
    problem.prior_row_k = PRIOR_ROW_TOUCH_K  # weak linear priors: 1 K rows pull the drifts
    truth = problem.start()
    names = [p.name for p in problem.per_touch]
    for i, _, f_heated, f_passive in EVENTS:
        for ch, f in (("heated", f_heated), ("passive", f_passive)):
            truth[problem.n_free + names.index(f"event0.{ch}_log_factor") * problem.n + i] = math.log(f)
    cols, power, _ = problem.design(truth)
    rng = np.random.default_rng(3)
    for i in range(problem.n):
        obj_c = 5.0 + 3.0 * i  # objects 17-25 K below the heated channel, 8-17 K below the passive
        for c, (r0, drift) in enumerate(((29.5, 0.05), (22.0, -0.02))):
            curve = (
                r0 * cols[c, i, :, 0] + drift * cols[c, i, :, 1] + obj_c * cols[c, i, :, 2] + (c == 0) * 30.0 * power[i]
            )
            sigma = noise[("heated", "passive")[c]]["white_k"]
            problem.x[c, i] = np.where(problem.mask[i], curve + rng.normal(0.0, sigma, curve.shape), 0.0)
    return problem, truth, noise


def _event_columns(problem: CalibrationProblem) -> np.ndarray:
    names = [p.name for p in problem.per_touch]
    groups = [g for g, name in enumerate(names) if name.startswith("event")]
    return np.array([problem.n_free + g * problem.n + i for g in groups for i in range(problem.n)])


@pytest.fixture(scope="module")
def placed(
    simulated: tuple[CalibrationProblem, np.ndarray, dict[str, dict[str, float]]],
) -> tuple[CalibrationProblem, np.ndarray, list[list[float]], np.ndarray]:
    """The same data as a problem without events (its truth otherwise), and the events placed."""
    problem, truth, _ = simulated
    plain = copy.copy(problem)
    plain.event_t = None
    plain = plain.with_touch_contact()
    free = truth[: plain.n_free + len(plain.per_touch) * plain.n]
    times, logs = place_events(plain, free, FIT_HZ)
    return plain, free, times, logs


def test_events_are_placed_at_the_steps_and_nowhere_else(
    placed: tuple[CalibrationProblem, np.ndarray, list[list[float]], np.ndarray],
) -> None:
    _, _, times, logs = placed
    # no event on the touches without a step (their residual is noise: no kink)
    assert times[3] == []
    for i, t_k, f_heated, f_passive in EVENTS:
        if f_heated == 1.0:
            assert times[i] == []
            continue
        near = int(np.argmin([abs(t - t_k) for t in times[i]]))
        assert abs(times[i][near] - t_k) <= 0.1, times[i]
        # the placement's own step sizes start the fit near the truth (first order in log f)
        assert abs(logs[0, i, near] - math.log(f_heated)) < 0.1 and abs(logs[1, i, near] - math.log(f_passive)) < 0.1


def test_the_factors_are_recovered_and_no_step_is_invented(
    simulated: tuple[CalibrationProblem, np.ndarray, dict[str, dict[str, float]]],
    placed: tuple[CalibrationProblem, np.ndarray, list[list[float]], np.ndarray],
) -> None:
    """From the placed events and their first-order sizes, a fit of every event's factors and
    time (the touches' own contacts and everything else at the truth) gives the steps back; any
    other event placed stays at no step."""
    _, _, noise = simulated
    plain, free, times, logs = placed
    problem = plain.with_events(times).with_touch_contact()
    problem.prior_row_k = plain.prior_row_k
    cols = _event_columns(problem)
    x0 = np.concatenate(
        [free, *[np.r_[logs[0, :, k], logs[1, :, k], np.zeros(problem.n)] for k in range(logs.shape[2])]]
    )
    lo, hi = problem.bounds()

    def residuals(theta: np.ndarray) -> np.ndarray:
        x = x0.copy()
        x[cols] = theta
        return problem.residuals(x)

    fit = optimize.least_squares(
        residuals,
        np.clip(x0[cols], lo[cols] + 1e-9, hi[cols] - 1e-9),
        bounds=(lo[cols], hi[cols]),
        x_scale="jac",
        diff_step=1e-5,
    )
    x = x0.copy()
    x[cols] = fit.x
    events = problem.events(x)
    assert events is not None
    fitted_t, factors = events
    for i, t_k, f_heated, f_passive in EVENTS:
        if f_heated == 1.0:
            continue
        near = int(np.nanargmin(np.abs(fitted_t[i] - t_k)))
        assert abs(fitted_t[i, near] - t_k) < 0.03
        assert abs(factors[0, i, near] / f_heated - 1) < 0.03 and abs(factors[1, i, near] / f_passive - 1) < 0.03, (
            i,
            factors[:, i],
        )
        others = [k for k in range(len(times[i])) if k != near]
        assert np.all(np.abs(np.log(factors[:, i, others])) < 0.03), factors[:, i]
    res, _, _ = problem.solve(x)
    for c, ch in enumerate(("heated", "passive")):
        assert np.sqrt(np.mean(res[c][problem.mask] ** 2)) < 1.5 * noise[ch]["white_k"]
