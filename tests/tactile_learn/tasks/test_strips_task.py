"""The strips task: input checks, evaluation data, ambiguity groups and pairing, metrics, training batches."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from synth.errors import DataError, InputError
from synth.scene import Scene
from synth.sensors import sensor_module
from tactile_learn.tasks import get_task
from tactile_learn.tasks.base import EvalData, readable_frames
from tactile_learn.tasks.strips import frame_groups, ghost_energy, pairing
from tests.conftest import tiny_strips_scene

TASK = get_task("strips")


@pytest.fixture(scope="module")
def scene() -> Scene:
    return tiny_strips_scene(count=[1, 2])


@pytest.fixture(scope="module")
def arrays(scene: Scene) -> dict[str, np.ndarray]:
    return sensor_module("strips").make_simulator(scene).simulate(30, np.random.default_rng(3))


def eval_data(scene: Scene, arrays: dict[str, np.ndarray]) -> EvalData:
    """The readable frames (a strong press may saturate the tiny sensor's ADC: no method may read it)."""
    extra = {k: v for k, v in arrays.items() if k.startswith("latent_")}
    data = EvalData(inputs=arrays["readings"], truth={"pressure": arrays["pressure"]}, scene=scene, extra=extra)
    readable, left_out = readable_frames(TASK, data)
    assert left_out["share"] < 0.2
    return readable


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda x: x[:, :-1], "expected shape"),
        (lambda x: x[0], "batch axis"),
        (lambda x: np.where(np.arange(x.shape[1]) == 2, np.nan, x), "NaN"),
        (lambda x: -x, "negative"),
        (lambda x: x * 0 + 1e3, "full scale"),
    ],
)
def test_bad_readings_are_refused_with_the_problem_named(
    scene: Scene, arrays: dict[str, np.ndarray], change: object, message: str
) -> None:
    with pytest.raises(InputError, match=message):
        TASK.check_inputs(change(arrays["readings"]), scene)  # type: ignore[operator]


def test_evaluation_data_of_another_sensor_or_without_maps_is_refused(
    tmp_path: Path, scene: Scene, arrays: dict[str, np.ndarray]
) -> None:
    wrong = tmp_path / "wrong.npz"
    np.savez(wrong, readings=arrays["readings"][:, :-2], pressure=arrays["pressure"])
    with pytest.raises(DataError, match="readings have shape"):
        TASK.load_eval_data(wrong, scene)
    no_maps = tmp_path / "no_maps.npz"
    np.savez(no_maps, readings=arrays["readings"])
    with pytest.raises(DataError, match="pressure"):
        TASK.load_eval_data(no_maps, scene)


def two_contacts(
    force: tuple[float, float], radius: tuple[float, float], xy: list[list[float]]
) -> dict[str, np.ndarray]:
    return {
        "latent_n_contacts": np.array([2]),
        "latent_force_n": np.array([force]),
        "latent_radius_mm": np.array([radius]),
        "latent_xy_mm": np.array([xy]),
    }


def test_twins_are_two_alike_contacts_on_distinct_rows_and_columns() -> None:
    pitch = 2.5
    twins = two_contacts((2.0, 2.1), (3.0, 3.0), [[1.0, 1.0], [8.0, 9.0]])
    same_row = two_contacts((2.0, 2.1), (3.0, 3.0), [[1.0, 1.0], [8.0, 2.0]])
    unlike = two_contacts((2.0, 4.0), (3.0, 3.0), [[1.0, 1.0], [8.0, 9.0]])
    assert frame_groups(twins, pitch)["two_twins"].tolist() == [True]
    assert frame_groups(same_row, pitch)["two_distinct"].tolist() == [True]
    assert frame_groups(unlike, pitch)["two_distinct"].tolist() == [True]


def test_pairing_and_ghost_energy_read_the_real_and_ghost_crossings() -> None:
    pitch = 2.5
    extra = two_contacts((2.0, 2.0), (3.0, 3.0), [[1.0, 1.0], [8.0, 9.0]])  # cells (0, 0) and (3, 3)
    real = np.zeros((1, 6, 5), dtype=np.float32)
    real[0, 0, 0] = real[0, 3, 3] = 1.0
    ghosts = np.zeros_like(real)
    ghosts[0, 0, 3] = ghosts[0, 3, 0] = 1.0
    assert ghost_energy(real, extra, pitch).tolist() == [0.0]
    assert ghost_energy(ghosts, extra, pitch).tolist() == [1.0]
    assert ghost_energy(real + ghosts, extra, pitch).tolist() == [0.5]
    assert ghost_energy(np.zeros_like(real), extra, pitch).tolist() == [0.0]  # empty: no ghost load, not 0/0
    assert pairing(real, extra, pitch)["confident_right"] == 1.0
    assert pairing(ghosts, extra, pitch)["confident_wrong"] == 1.0
    assert pairing(real + ghosts, extra, pitch)["spread"] == 1.0


def test_the_truth_scores_perfectly_and_explains_the_readings_better_than_a_flat_map(
    scene: Scene, arrays: dict[str, np.ndarray]
) -> None:
    data = eval_data(scene, arrays)
    truth = data.truth["pressure"]
    perfect = TASK.metrics(truth, data)
    assert perfect["pearson_r_mean"] == pytest.approx(1.0)
    assert perfect["nrmse"] == pytest.approx(0.0, abs=1e-6)
    assert perfect["peak_err_mm_median"] == pytest.approx(0.0, abs=1e-9)
    assert set(perfect["by_group"]) <= {"one_contact", "two_distinct", "two_twins"}
    flat = TASK.metrics(np.full_like(truth, truth.mean()), data)
    assert flat["pearson_r_mean"] == pytest.approx(0.0, abs=1e-6)
    assert flat["residual_sigma_median"] > perfect["residual_sigma_median"]


def test_every_classical_method_is_evaluated_with_the_same_metrics(scene: Scene, arrays: dict[str, np.ndarray]) -> None:
    data = eval_data(scene, arrays)
    for name, factory in TASK.classical_methods().items():
        result = TASK.evaluate(factory(scene), data)
        assert 0.3 < result["pearson_r_mean"] <= 1.0, name
        assert np.isfinite(result["residual_rel_median"]), name


def test_training_batches_mirror_readings_and_maps_together(scene: Scene, arrays: dict[str, np.ndarray]) -> None:
    x, targets = TASK.training_batch(arrays, scene, np.random.default_rng(1))
    pressure = targets["pressure"]
    assert x.dtype == np.float32 and x.shape == arrays["readings"].shape
    rows = scene.sensor.geometry.n_rows
    flips = {"none": 0, "y": 0, "x": 0, "both": 0}
    for b in range(len(x)):
        original, readings = arrays["pressure"][b], arrays["readings"][b]
        options = {
            "none": (original, readings),
            "y": (original[::-1, :], np.concatenate([readings[:rows][::-1], readings[rows:]])),
            "x": (original[:, ::-1], np.concatenate([readings[:rows], readings[rows:][::-1]])),
            "both": (original[::-1, ::-1], np.concatenate([readings[:rows][::-1], readings[rows:][::-1]])),
        }
        matches = [k for k, (m, r) in options.items() if np.array_equal(pressure[b], m) and np.array_equal(x[b], r)]
        assert matches, f"frame {b}: readings and map were not mirrored together"
        flips[matches[-1]] += 1
    assert flips["none"] < len(x)  # mirroring happens
