"""The few-shot classifiers of real touches: press time, press-aligned features that do not change
with the press speed, the nearest labelled touch on classes with two modes, and clear errors."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from synth.errors import ConfigError
from tactile_learn.estimators.classical.aligned_pca import aligned_curves
from tactile_learn.estimators.classical.press_aligned import NearestTouch, press_aligned_features, press_time
from tactile_learn.few_shot import FEW_SHOT_METHODS, few_shot_predict, leave_one_out
from tactile_learn.thermal_recordings import press_onset, press_profile

FS = 200.0
T = np.arange(int(8 * FS)) / FS


def ramp_press(start_s: float, rise_s: float) -> np.ndarray:
    """Force / plateau: 0, a linear rise over ``rise_s`` from ``start_s``, then 1."""
    return np.clip((T - start_s) / rise_s, 0.0, 1.0)


def curve_of_press(press: np.ndarray, drop_k: float, rate: float) -> np.ndarray:
    """A heated curve that depends on press time alone: drop_k (1 - exp(-rate tau)) after the touch."""
    tau = np.concatenate([[0.0], np.cumsum(0.5 * (press[1:] + press[:-1]) / FS)])
    return 29.5 - drop_k * (1.0 - np.exp(-rate * tau))


def test_press_time_is_the_running_integral_of_the_press() -> None:
    press = ramp_press(1.0, 1.0)[None, :]
    tau = press_time(press, np.array([True]), np.array([1.5]), FS)[0]
    first = int(np.argmax(press[0] >= 0.05))
    # before the first touch: clock time to it; during the ramp: (t - 1)^2 / 2; after it: t - 1.5
    np.testing.assert_allclose(tau[:first], T[:first] - T[first], atol=1e-12)
    assert tau[int(1.8 * FS)] == pytest.approx(0.8**2 / 2, abs=2e-3)
    assert tau[int(5.0 * FS)] == pytest.approx(3.5, abs=2e-3)
    # without a force record the clock runs from the onset
    bare = press_time(press, np.array([False]), np.array([1.5]), FS)[0]
    np.testing.assert_allclose(bare, T - 1.5)


def test_press_aligned_features_do_not_change_with_the_press_speed() -> None:
    fast, slow = ramp_press(1.0, 0.3), ramp_press(0.8, 1.6)
    press = np.stack([fast, slow])
    heated = np.stack([curve_of_press(fast, 2.0, 0.8), curve_of_press(slow, 2.0, 0.8)])
    onset = np.array([press_onset(T, p) for p in press])
    feats = press_aligned_features([heated], press, np.array([True, True]), onset, FS, 4.0)
    clock = aligned_curves([heated], onset, FS, 4.0)
    # the same material pressed fast and slowly: the press-aligned features agree to 1 %, the
    # onset-aligned curves differ by a tenth of the drop
    assert np.abs(feats[0] - feats[1]).max() < 0.01 * np.abs(feats).max()
    assert np.abs(clock[0] - clock[1]).max() > 0.1 * 2.0


def test_nearest_touch_keeps_a_class_with_two_modes() -> None:
    # class 1 ("wood") at two places (room temperature, cooled), class 0 ("metal") between them
    x = np.array([[-2.0, 0.0], [-2.1, 0.1], [2.0, 0.0], [2.1, -0.1], [0.0, 0.0], [0.1, 0.1]])
    y = np.array([1, 1, 1, 1, 0, 0])
    model = NearestTouch().fit(x, y, 3)
    proba = model.predict_proba(np.array([[-1.9, 0.0], [1.8, 0.0], [0.05, -0.05]]))
    assert proba.argmax(axis=1).tolist() == [1, 1, 0]
    np.testing.assert_allclose(proba.sum(axis=1), 1.0)
    assert (proba[:, 2] == 0).all()  # a class without a labelled touch is never answered
    assert np.isfinite(proba).all()


def test_press_profile_and_errors() -> None:
    assert press_profile(T, np.zeros_like(T)) is None
    profile = press_profile(T, 7.0 * ramp_press(1.0, 0.5))
    assert profile is not None and profile.max() == pytest.approx(1.0)
    with pytest.raises(ValueError, match="points"):
        press_aligned_features([T[None]], T[None], np.array([True]), np.array([1.0]), FS, 1.0, points=1)


def test_few_shot_predict_names_its_problem() -> None:
    from tactile_learn.tasks.base import EvalData

    class _Scene:
        name = "s"

    data = EvalData(inputs=np.zeros((2, 0)), truth={"label": np.array([2, 2])}, scene=_Scene())  # type: ignore[arg-type]
    data.extra["labelled"] = np.array([False, False])
    with pytest.raises(ConfigError, match="no labelled touch"):
        few_shot_predict("press_aligned", data, data, 1.0)
    with pytest.raises(ConfigError, match="not one of"):
        few_shot_predict("svm", data, data, 1.0)
    with pytest.raises(ConfigError, match="3 or more"):
        leave_one_out("press_aligned", data, 1.0)


def test_few_shot_on_simulated_recordings_with_leave_one_out(tmp_path: Path) -> None:
    """Recordings as a user writes them (force column, labels): both few-shot methods train on one
    set of simulated touches and classify another (a different seed) by more than chance; the
    leave-one-out check runs on the labelled touches alone and is a fraction."""
    from synth.config import replace
    from tactile_learn.cli import main
    from tactile_learn.tasks.thermal import ThermalTask
    from tactile_learn.thermal_adapt import write_scene
    from tactile_learn.thermal_recordings import write_recordings
    from tests.tactile_learn.test_thermal_real import robot_scene, robot_touches

    scene = robot_scene()
    heated = dataclasses.replace(scene, sensor=replace(scene.sensor, "channels", ["heated"]))  # type: ignore[arg-type]
    write_recordings(tmp_path / "train", robot_touches(12, 5))
    write_recordings(tmp_path / "test", robot_touches(30, 6))
    task = ThermalTask()
    train, test = task.load_eval_data(tmp_path / "train", heated), task.load_eval_data(tmp_path / "test", heated)
    assert train.extra["has_press"].all() and train.extra["press"].max() == pytest.approx(1.0, abs=0.05)
    for method in FEW_SHOT_METHODS:
        proba = few_shot_predict(method, train, test, 4.0)
        assert proba.shape == (30, 2) and np.isfinite(proba).all()
        assert (proba.argmax(axis=1) == test.truth["label"]).mean() > 0.6, method
        loo = leave_one_out(method, train, 4.0)
        assert 0.0 <= loo <= 1.0
    # touches without a force record (simulated ones): press time falls back to clock time
    bare = test.subset(np.arange(len(test)))
    del bare.extra["press"], bare.extra["has_press"]
    proba = few_shot_predict("press_aligned", train, bare, 4.0)
    assert proba.shape == (30, 2) and np.isfinite(proba).all()
    # the same from the command line, with the scene a user's calibration writes
    write_scene(heated, tmp_path / "sensor.toml")
    args = ["eval", "--task", "thermal", "--data", str(tmp_path / "test"), "--method", "press_aligned"]
    args += ["--scene", str(tmp_path / "sensor.toml"), "--durations", "1,4", "--group-by", "condition"]
    assert main([*args, "--train", str(tmp_path / "train"), "--json", str(tmp_path / "out.json")]) == 0
    metrics = json.loads((tmp_path / "out.json").read_text())["metrics"]
    assert set(metrics["accuracy_by_duration"]) == {"1.0", "4.0"} == set(metrics["leave_one_out_by_duration"])
    assert metrics["accuracy_by_duration"]["4.0"] > 0.6 and set(metrics["by_group"]) == {"cold", "room"}
    assert main(args) == 2  # no --train: a clear error
    assert main([*args[:-4], "--method", "curve_match", "--train", str(tmp_path / "train")]) == 2
