"""The projection estimator: the intersection estimate refined until it explains the readings."""

from __future__ import annotations

import numpy as np
import pytest

from synth.scene import Scene, load_scene
from synth.sensors import sensor_module
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.strips_consistency import StripConsistency
from tactile_learn.tasks import get_task
from tactile_learn.tasks.strips import ghost_energy
from tests.conftest import tiny_strips_scene


def estimators(scene: Scene, **projection: float) -> tuple[object, object]:
    methods = get_task("strips").classical_methods()
    return methods["intersection"](scene), methods["projection"](scene, **projection)


def frames(scene: Scene, n: int, seed: int) -> dict[str, np.ndarray]:
    return sensor_module(scene.task).make_simulator(scene).simulate(n, np.random.default_rng(seed))


@pytest.fixture(scope="module")
def tiny() -> tuple[Scene, dict[str, np.ndarray]]:
    scene = tiny_strips_scene(count=[1, 2])
    return scene, frames(scene, 40, seed=5)


def test_projection_explains_the_readings_better_than_its_start(tiny: tuple[Scene, dict[str, np.ndarray]]) -> None:
    scene, data = tiny
    intersection, projection = estimators(scene)
    start = intersection.predict(data["readings"])
    refined = projection.predict(data["readings"])
    check = StripConsistency(scene)
    before = check.residual(data["readings"], start)["residual_sigma"]
    after = check.residual(data["readings"], refined)["residual_sigma"]
    assert np.median(after) < 0.8 * np.median(before)
    assert np.mean(after <= before + 1e-6) > 0.9  # it rarely makes a frame worse


def test_projection_is_non_negative_and_never_lights_a_dark_cell(tiny: tuple[Scene, dict[str, np.ndarray]]) -> None:
    scene, data = tiny
    intersection, projection = estimators(scene)
    start = intersection.predict(data["readings"])
    refined = projection.predict(data["readings"])
    assert refined.dtype == np.float32 and refined.shape == data["pressure"].shape
    assert np.all(refined >= 0) and np.all(np.isfinite(refined))
    assert np.all(refined[start == 0] == 0)  # multiplicative updates keep dark cells dark


def test_no_iterations_return_the_intersection_estimate(tiny: tuple[Scene, dict[str, np.ndarray]]) -> None:
    scene, data = tiny
    intersection, projection = estimators(scene, max_iter=0)
    np.testing.assert_array_equal(projection.predict(data["readings"]), intersection.predict(data["readings"]))


def test_projection_is_more_accurate_than_intersection_on_its_own_sensor(
    tiny: tuple[Scene, dict[str, np.ndarray]],
) -> None:
    scene, data = tiny
    intersection, projection = estimators(scene)
    r_start = np.nanmean(pearson_per_frame(intersection.predict(data["readings"]), data["pressure"]))
    r_refined = np.nanmean(pearson_per_frame(projection.predict(data["readings"]), data["pressure"]))
    assert r_refined > r_start


def test_a_diagonal_layer_lets_projection_pull_down_the_ghosts_intersection_keeps() -> None:
    scene = load_scene("strips16_twins_diagonal")
    data = frames(scene, 12, seed=13)
    extra = {k: v for k, v in data.items() if k.startswith("latent_")}
    pitch = scene.sensor.geometry.pitch_mm
    intersection, projection = estimators(scene)
    ghosts_start = ghost_energy(intersection.predict(data["readings"]), extra, pitch)
    ghosts_refined = ghost_energy(projection.predict(data["readings"]), extra, pitch)
    # intersection reads only row and column totals: two identical contacts leave it half on the ghosts
    assert np.median(ghosts_start) > 0.1
    assert np.median(ghosts_refined) < 0.5 * np.median(ghosts_start)
