"""The fsr task: data loading, metrics, calibration and the learning hooks."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from synth.config import replace
from synth.dataset import generate
from synth.errors import DataError, InputError
from synth.scene import Scene, load_scene
from synth.sensors import fsr
from tactile_learn.tasks import get_task
from tactile_learn.tasks.fsr import COLUMNS, FsrTask, calibrate_gains, fsr_metrics, to_nominal_film

SCENE = load_scene("fsr6")
TASK = FsrTask()


def _simulate(n: int, seed: int, scene: Scene = SCENE) -> dict[str, np.ndarray]:
    return fsr.make_simulator(scene).simulate(n, np.random.default_rng(seed))


def test_registry_and_contract() -> None:
    task = get_task("fsr")
    assert isinstance(task, FsrTask)
    assert task.default_scene == "fsr6" and task.input_key == "readings"
    assert task.input_shape(SCENE) == (6,)
    assert task.primary_metric == ("loc_err_mm_median", False)
    readings = _simulate(50, 0)["readings"]
    for name, factory in task.classical_methods().items():
        estimator = factory(SCENE)
        assert estimator.name == name and estimator.task == "fsr"
        pred = estimator.predict(readings)
        assert pred.shape == (50, len(COLUMNS)) and pred.dtype == np.float32
        assert estimator.predict(np.zeros((0, 6), np.float32)).shape == (0, len(COLUMNS))


def test_perfect_prediction_scores_perfectly() -> None:
    data = _simulate(2000, 1)
    contact = data["force_n"] > 0
    inside = fsr.in_triangles(data["xy_mm"].astype(np.float64), SCENE.sensor.layout)
    one_press = np.ones_like(contact)
    pred = np.concatenate(
        [data["xy_mm"], data["force_n"][:, None], contact[:, None], inside[:, None], one_press[:, None]], axis=1
    ).astype(np.float32)
    m = fsr_metrics(pred, data["xy_mm"], data["force_n"], SCENE.sensor.layout)
    for suffix in ("", "_inside", "_film"):
        assert m[f"loc_err_mm_median{suffix}"] == pytest.approx(0.0, abs=1e-5)
        assert m[f"force_accuracy{suffix}"] == pytest.approx(1.0, abs=1e-6)
        assert m[f"detect_accuracy{suffix}"] == 1.0
    assert m["inside_accuracy"] == 1.0
    assert 0 < m["n_contacts"] < m["n_contacts_inside"] < m["n_contacts_film"] < m["n_frames"]
    json.dumps(m)  # plain floats


def test_metrics_definitions() -> None:
    """force_accuracy is the paper's 1 - mean |F_est - F| / F; errors are in mm."""
    xy = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    force = np.array([2.0, 4.0, 0.0])
    pred = np.array([[3.0, 4.0, 3.0, 1, 1, 1], [0.0, 1.0, 4.0, 1, 1, 0], [9.0, 9.0, 9.0, 0.2, 0, 1]], np.float32)
    m = fsr_metrics(pred, xy, force, SCENE.sensor.layout)
    assert m["loc_err_mm_median"] == pytest.approx(3.0)
    assert m["force_accuracy"] == pytest.approx(1 - (0.5 + 0.0) / 2)
    assert m["force_err_pct_median"] == pytest.approx(25.0)
    assert m["detect_accuracy"] == 1.0
    assert m["flagged_rate"] == pytest.approx(0.5)  # one of the two detected presses is flagged


def test_load_eval_data_from_npz_and_dataset(tmp_path: Path) -> None:
    data = _simulate(64, 2)
    npz = tmp_path / "mine.npz"
    xy = data["xy_mm"].copy()
    xy[data["force_n"] == 0] = np.nan  # allowed on frames without contact
    np.savez(npz, readings=data["readings"], xy_mm=xy, force_n=data["force_n"])
    loaded = TASK.load_eval_data(npz)
    assert loaded.inputs.shape == (64, 6) and np.isfinite(loaded.truth["xy_mm"]).all()
    assert loaded.scene.name == "fsr6"
    folder = tmp_path / "ds"
    generate(SCENE, 300, 5, folder, shard_size=128)
    from_folder = TASK.load_eval_data(folder)
    assert len(from_folder) == 300 and "latent_film_id" in from_folder.extra
    np.savez(tmp_path / "bad.npz", readings=data["readings"], xy_mm=data["xy_mm"])
    with pytest.raises(DataError, match="force_n"):
        TASK.load_eval_data(tmp_path / "bad.npz")
    np.savez(tmp_path / "bad2.npz", readings=data["readings"][:, :5], xy_mm=data["xy_mm"], force_n=data["force_n"])
    with pytest.raises(DataError, match="readings have shape"):
        TASK.load_eval_data(tmp_path / "bad2.npz")


def test_check_inputs_errors_are_clear() -> None:
    with pytest.raises(InputError, match="negative"):
        TASK.check_inputs(np.array([[1, 2, 3, 4, 5, -1]]), SCENE)
    with pytest.raises(InputError, match="NaN"):
        TASK.check_inputs(np.array([[1, 2, 3, 4, 5, np.nan]]), SCENE)
    with pytest.raises(InputError, match=r"\('B', 6\)"):
        TASK.check_inputs(np.ones((3, 7)), SCENE)
    with pytest.raises(InputError, match="10-bit ADC's full scale"):
        TASK.check_inputs(np.array([[1, 2, 3, 4, 5, 1023]]), SCENE)


def _film_scene(gains: tuple[float, ...]) -> Scene:
    return dataclasses.replace(SCENE, sensor=replace(SCENE.sensor, "film.gains", list(gains)))


def _presses_on_sensors(scene: Scene, per_sensor: int, seed: int) -> dict[str, np.ndarray]:
    """Known presses on top of every sensor (the calibration procedure), on ``scene``'s film."""
    rng = np.random.default_rng(seed)
    pos = fsr.sensor_positions(scene.sensor.layout)
    xy = np.repeat(pos, per_sensor, axis=0) + rng.normal(0, 0.3, (6 * per_sensor, 2))
    force = rng.uniform(2.0, 8.0, 6 * per_sensor)
    sim = fsr.make_simulator(scene)
    gains = np.asarray(scene.sensor.film.gains) * (
        1 + scene.sensor.film.repeatability * rng.uniform(-1, 1, (len(force), 6))
    )
    readings = sim.forward(xy, force, 4.0, gains=gains, rng=rng)
    return {
        "readings": readings.astype(np.float32),
        "xy_mm": xy.astype(np.float32),
        "force_n": force.astype(np.float32),
    }


def test_calibration_recovers_the_film_gains(tmp_path: Path) -> None:
    true = (1.06, 0.94, 1.03, 0.97, 1.0, 1.05)
    film = _film_scene(true)
    presses = _presses_on_sensors(film, 3, 0)
    gains, used = calibrate_gains(presses["readings"], presses["xy_mm"], presses["force_n"], SCENE.sensor)
    assert np.all(used >= 3)
    np.testing.assert_allclose(gains, true, rtol=0.02)
    np.savez(tmp_path / "presses.npz", **presses)
    out = tmp_path / "my_film.toml"
    summary = TASK.calibrate(tmp_path / "presses.npz", out, SCENE)
    assert summary["n_presses"] == 18
    calibrated = load_scene(out)
    assert calibrated.sensor.film.gains is not None
    np.testing.assert_allclose(calibrated.sensor.film.gains, true, rtol=0.02)
    # with the calibrated scene, the film's readings map to the nominal film's
    frames = _simulate(400, 9, film.with_noise(False))
    nominal = _simulate(400, 9, SCENE.with_noise(False))
    mapped = TASK.check_inputs(frames["readings"], calibrated)
    big = nominal["readings"] > 50
    np.testing.assert_allclose(mapped[big], nominal["readings"][big], rtol=0.03, atol=2.0)


def test_calibration_needs_every_sensor(tmp_path: Path) -> None:
    presses = _presses_on_sensors(_film_scene((1.0,) * 6), 2, 1)
    keep = np.arange(12) >= 2  # drop the presses on S0
    np.savez(tmp_path / "p.npz", **{k: v[keep] for k, v in presses.items()})
    with pytest.raises(DataError, match="S0"):
        TASK.calibrate(tmp_path / "p.npz", tmp_path / "out.toml", SCENE)


def test_to_nominal_film_is_the_identity_for_unit_gains() -> None:
    readings = _simulate(200, 4)["readings"]
    mapped = to_nominal_film(readings, SCENE.sensor, np.ones(6))
    np.testing.assert_allclose(mapped, readings, atol=1e-3)


# ---- learning hooks ----------------------------------------------------------------------------


@pytest.fixture
def torch() -> Any:
    """The learning hooks need torch; a deployment without it still runs the tests above."""
    return pytest.importorskip("torch", reason="torch (training extra) is not installed")


def test_learning_hooks_shapes_and_finite_loss(torch: Any) -> None:
    data = _simulate(512, 6)
    stats = TASK.fit_stats(data, SCENE)
    json.dumps(stats)
    x, targets = TASK.training_batch(data, SCENE, np.random.default_rng(0))
    assert x.shape == (512, 6) and x.dtype == np.float32
    assert all(v.dtype == np.float32 and len(v) == 512 for v in targets.values())
    assert targets["contact"].sum() <= targets["position_weight"].sum()  # felt contacts are contacts
    for size in TASK.net_sizes:
        torch.manual_seed(0)
        net = TASK.build_net(size, SCENE, stats)
        out = net(torch.from_numpy(x))
        assert out.shape == (512, 5)
        assert torch.all(out[:, 2] > 0) and torch.all((out[:, 3:] >= 0) & (out[:, 3:] <= 1))
        raw = TASK.train_forward(net, torch.from_numpy(x))
        loss = TASK.loss(raw, {k: torch.from_numpy(v) for k, v in targets.items()})
        assert torch.isfinite(loss)
        loss.backward()


def test_a_few_steps_lower_the_loss(torch: Any) -> None:
    torch.set_num_threads(1)
    data = _simulate(2048, 7)
    stats = TASK.fit_stats(data, SCENE)
    torch.manual_seed(0)
    net = TASK.build_net("small", SCENE, stats)
    opt = torch.optim.Adam(net.parameters(), lr=3e-3)
    x, targets = TASK.training_batch(data, SCENE, np.random.default_rng(0))
    xt, tt = torch.from_numpy(x), {k: torch.from_numpy(v) for k, v in targets.items()}
    first = TASK.loss(TASK.train_forward(net, xt), tt).item()
    for _ in range(60):
        loss = TASK.loss(TASK.train_forward(net, xt), tt)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.7 * first


def test_features_float32_match_float64(torch: Any) -> None:
    from tactile_learn.nets.fsr import FsrFeatures, _log_conductance

    readings = np.concatenate([_simulate(300, 8)["readings"], np.array([[0, 1, 511, 1000, 1022, 3]], np.float32)])
    ref = _log_conductance(readings, 10)
    features = FsrFeatures(10, [0.0] * 6, [1.0] * 6)
    got = features(torch.from_numpy(readings)).numpy()
    np.testing.assert_allclose(got, ref, rtol=1e-5, atol=1e-5)
