"""FSR film: two simultaneous presses and large flat indenters are simulated, and the one-press
check flags them instead of letting a confident wrong position through."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from synth.config import replace
from synth.scene import Scene, load_scene
from synth.sensors import fsr
from tactile_learn.fsr_check import OnePressCheck
from tactile_learn.tasks import get_task
from tests.paths import REPO_ROOT

BASE = load_scene("fsr6")


def scene(**stimulus: object) -> Scene:
    config = BASE.sensor
    for key, value in {
        "no_contact_fraction": 0.0,
        "inside_fraction": 1.0,
        "force_range_n": (1.0, 10.0),
        **stimulus,
    }.items():
        config = replace(config, f"stimulus.{key}", value)
    import dataclasses

    return dataclasses.replace(BASE, sensor=config)


def simulate(sc: Scene, n: int, seed: int) -> dict[str, np.ndarray]:
    return fsr.make_simulator(sc).simulate(n, np.random.default_rng(seed))


def test_plain_scenes_keep_their_stream_and_digest() -> None:
    """The new stimulus options default to off: fsr6 draws and stores what it did."""
    out = simulate(BASE, 64, 1)
    assert "latent_n_presses" not in out
    import json

    card = json.loads((REPO_ROOT / "models" / "fsr.json").read_text())
    assert card["scene_digest"] == BASE.digest


def test_second_presses_add_their_load_and_flat_indenters_spread_it() -> None:
    config = BASE.sensor
    xy = np.array([[0.0, 0.0], [10.0, -5.0]])
    one = fsr.sensor_loads(config, xy[:1], np.array([3.0]), np.array([4.0]))
    other = fsr.sensor_loads(config, xy[1:], np.array([2.0]), np.array([4.0]))
    out = simulate(scene(second_press_fraction=1.0), 400, 2)
    assert (out["latent_n_presses"] == 2).all() and (out["latent_second_force_n"] > 0).all()
    # the load path is linear: two presses load the discs with the sum of their loads
    assert np.allclose(one + other, fsr.sensor_loads(config, xy, np.array([3.0, 2.0]), np.array([4.0, 4.0])).sum(0))
    # a flat disc shrinking to a point carries the point load; a wide one spreads it over more discs
    point = fsr.sensor_loads(config, xy[:1], np.array([3.0]), np.array([0.3]))
    tiny = fsr.flat_sensor_loads(config, xy[:1], np.array([3.0]), np.array([0.05]))
    wide = fsr.flat_sensor_loads(config, xy[:1], np.array([3.0]), np.array([18.0]))
    assert np.allclose(tiny, point, rtol=0.02)
    assert wide.max() < point.max() and np.sort(wide[0])[2] > np.sort(point[0])[2]
    flats = simulate(scene(flat_fraction=1.0), 50, 3)
    assert flats["latent_flat"].all() and (flats["latent_flat_radius_mm"] >= 10).all()


@pytest.mark.parametrize("method", ["triangulation", "fsr"])
def test_two_presses_and_flat_indenters_are_flagged_single_presses_are_not(method: str, tmp_path: Path) -> None:
    from tactile_learn.methods import resolve_method

    task = get_task("fsr")
    est = resolve_method("fsr", method, BASE)
    rates = {}
    for name, sc in {
        "one": scene(),
        "two": scene(second_press_fraction=1.0),
        "flat": scene(flat_fraction=1.0),
    }.items():
        out = simulate(sc, 400, 5)
        pred = est.predict(out["readings"])
        assert pred.shape == (400, 6) and set(np.unique(pred[:, 5])) <= {0.0, 0.5, 1.0}
        detected = pred[:, 3] > 0.5
        rates[name] = float((pred[detected, 5] < 0.5).mean())
        if name == "two":
            metrics = task.metrics(pred, task.load_eval_data(_npz(out, tmp_path), sc))
    assert rates["one"] < 0.06
    assert rates["two"] > 0.4 and rates["flat"] > 0.25
    assert metrics["flag_rates"]["two_presses_flagged"] == pytest.approx(rates["two"], abs=1e-6)


def _npz(out: dict[str, np.ndarray], folder: Path) -> str:
    path = folder / "frames.npz"
    np.savez(path, **out)
    return str(path)


def test_check_residual_is_small_for_the_true_press_and_large_for_two() -> None:
    check = OnePressCheck(BASE)
    sim = fsr.make_simulator(BASE)
    xy = np.array([[0.0, 0.0], [-5.0, 3.0]])
    force = np.array([4.0, 2.0])
    readings = sim.forward(xy, force, 4.0)
    truth = np.column_stack([xy, force, np.ones(2), np.ones(2)])
    assert (check.residual(readings, truth) < 0.01).all()
    # start far from the truth: the refinement still finds the press
    off = truth.copy()
    off[:, :2] += 2.0
    assert (check.residual(readings, off) < check.threshold).all()
    both = sim.forward(np.array([[-10.0, -5.0]]), np.array([4.0]), 4.0)
    both = sim.readout.codes(
        sim.law.conductance_us(
            fsr.sensor_loads(BASE.sensor, np.array([[-10.0, -5.0], [10.0, -5.0]]), np.array([4.0, 4.0]), 4.0).sum(
                axis=0, keepdims=True
            ),
            1.0,
        )
    )
    estimate = np.array([[0.0, -5.0, 8.0, 1.0, 1.0]])
    assert check.residual(both, estimate)[0] > 3 * check.threshold
    assert check.p_one_press(both, estimate)[0] == 0.0
    assert check.p_one_press(both, np.array([[0.0, 0.0, 0.0, 0.0, 0.0]]))[0] == 0.0  # no contact: all zeros
