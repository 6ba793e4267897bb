"""A real thermal fingertip (issue 11): multi-channel recordings with a force column, the onset from
the force, labels as families or the user's classes, the real-sensor simulator (lags, heater,
drift, contact build-up, passive channel), calibration that recovers a known sensor and reports
itself, eval by duration and group, and adapt end to end."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from synth.config import replace
from synth.errors import ConfigError, DataError
from synth.scene import load_scene, parse_scene
from synth.sensors.thermal import make_simulator
from tactile_learn.calibration.thermal_problem import CalibrationProblem
from tactile_learn.calibration.thermal_touches import noise_levels, prepare_touches
from tactile_learn.cli import main
from tactile_learn.tasks.thermal import ThermalTask
from tactile_learn.thermal_adapt import calibrate_recordings, write_scene
from tactile_learn.thermal_recordings import Touch, press_onset, read_recordings, write_recordings

TASK = ThermalTask()

#: a robot fingertip like the thermal-robot recordings: two lags, a heater holding 29.5 degC whose
#: power then stays constant, a slight drift, a passive thermistor; metal and wood classes
ROBOT = {
    "name": "robot",
    "task": "thermal",
    "outputs": ["readings", "passive", "latent"],
    "thermal": {
        "grid": [1, 1],
        "window_s": 6.0,
        "channels": ["heated", "passive"],
        "sensor": {
            "heat_capacity_j_m2k": [4000.0, 4000.0],
            "loss_w_m2k": [600.0, 600.0],
            "heater_w_m2": [4200.0, 4200.0],
            "pixel_spread": 0.0,
            "ambient_c": [22.5, 22.5],
            "lag_s": [0.8, 0.8],
            "lag2_s": [0.5, 0.5],
            "heater": "constant",
            "set_point_c": [29.5, 29.5],
            "drift_k_s": [0.1, 0.1],
        },
        "contact": {
            "conductance_w_m2k": [1000.0, 1000.0],
            "pixel_conductance_spread": 0.0,
            "radius_mm": [3.0, 3.0],
            "onset_s": [2.5, 3.0],
            "onset_jitter_s": 0.0,
            "contact_s": [9.0, 9.0],
            "ramp_s": [0.0, 0.0],
        },
        "objects": {
            "classes": [{"name": "metal", "materials": ["aluminium"]}, {"name": "wood", "materials": ["oak"]}],
            "offset_k": [-10.0, 2.0],
            "second_object": 0.0,
            "property_spread": 0.0,
        },
        "passive": {
            "enabled": True,
            "heat_capacity_j_m2k": [1500.0, 1500.0],
            "loss_w_m2k": [200.0, 200.0],
            "conductance_w_m2k": [150.0, 150.0],
            "lag_s": [1.0, 1.0],
            "lag2_s": [0.05, 0.05],
        },
        "readout": {
            "sampling_hz": 100.0,
            "duration_s": 8.0,
            "noise_k": 0.0005,
            "adc_step_k": 0.0,
            "adc_range_c": [-50.0, 150.0],
        },
    },
}
CLASSES = {"metal": ("aluminium",), "wood": ("oak",)}
#: the force crosses half its plateau this long after the thermal contact starts
PRESS_LEAD_S = 0.2


def robot_scene(**changes: object) -> object:
    scene = parse_scene(json.loads(json.dumps(ROBOT)), "robot")
    config = scene.sensor
    for key, value in changes.items():
        config = replace(config, key, value)
    return dataclasses.replace(scene, sensor=config)


def simulated_series(
    scene: object, n: int, seed: int
) -> tuple[list[tuple[str, int, np.ndarray, np.ndarray, np.ndarray, float]], dict[str, dict[str, float]], dict]:
    """``n`` simulated touches of ``scene`` as the calibration's series (name, class, t, heated,
    passive, onset), the noise levels of both channels, and the simulator's arrays."""
    arrays = make_simulator(scene).simulate(n, np.random.default_rng(seed))  # type: ignore[arg-type]
    fs = scene.sensor.readout.sampling_hz  # type: ignore[attr-defined]
    t = np.arange(arrays["readings"].shape[-1]) / fs
    series, heated, passive = [], [], []
    for i in range(n):
        onset = float(arrays["latent_onset_s"][i, 0])
        h = arrays["readings"][i, 0].astype(np.float64)
        p = arrays["passive"][i, 0].astype(np.float64)
        series.append((f"t{i}", int(arrays["latent_class"][i, 0]), t, h, p, onset))
        heated.append((t, h, onset))
        passive.append((t, p, onset))
    return series, {"heated": noise_levels(heated), "passive": noise_levels(passive)}, arrays


def problems_without_and_with(nuisance: str, classes: list) -> tuple[CalibrationProblem, CalibrationProblem]:
    """Two simulated touches of the robot scene as heated + passive calibration problems: the
    default one and one with the opt-in ``nuisance`` term (a term's tests compare the two)."""
    series, _, _ = simulated_series(robot_scene(), 2, 5)
    touches = prepare_touches(series)
    return CalibrationProblem(touches, classes, True), CalibrationProblem(touches, classes, True, (nuisance,))


def robot_touches(n: int, seed: int, scene: object = None) -> list[Touch]:
    """Simulated touches as a logger writes them: time from 0, heated, passive and a force that
    reads 0 below its dead band, toggles at first touch and crosses half its plateau
    ``PRESS_LEAD_S`` after the thermal contact starts."""
    scene = scene or robot_scene()
    arrays = make_simulator(scene).simulate(n, np.random.default_rng(seed))  # type: ignore[arg-type]
    fs = scene.sensor.readout.sampling_hz  # type: ignore[attr-defined]
    t = np.arange(arrays["readings"].shape[-1]) / fs
    rng = np.random.default_rng(seed + 1)
    out = []
    for i in range(n):
        onset = float(arrays["latent_onset_s"][i, 0])
        force = np.clip((t - onset) / (2 * PRESS_LEAD_S), 0.0, 1.0) * 4.5
        force[force < 1.0] = 0.0  # the dead band
        flicker = (t > onset - 0.3) & (t < onset) & (rng.random(len(t)) < 0.5)
        force[flicker] = 1.0  # the dead band's first level, on and off before the press
        label = scene.sensor.class_names[int(arrays["latent_class"][i, 0])]  # type: ignore[attr-defined]
        out.append(
            Touch(
                file=f"t{i}.csv",
                time_s=t.copy(),
                temperature_c=arrays["readings"][i, 0].astype(np.float64),
                material=label,
                info={"condition": "cold" if arrays["latent_object_c"][i, 0] < 20 else "room"},
                passive_c=arrays["passive"][i, 0].astype(np.float64),
                force=force,
            )
        )
    return out


def test_seed_scenes_keep_their_digests() -> None:
    """The real-sensor fields are left out of a scene's plain data at their defaults: the shipped
    models' cards still match their scenes."""
    assert load_scene("thermal").digest == "9a66a724c6755986"
    assert load_scene("thermal_wns").digest == "6d3770139f6d9df7"


def test_real_sensor_scene_simulates_both_channels_deterministically() -> None:
    scene = robot_scene()
    a = make_simulator(scene).simulate(20, np.random.default_rng(3))  # type: ignore[arg-type]
    b = make_simulator(scene).simulate(20, np.random.default_rng(3))  # type: ignore[arg-type]
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert a["readings"].shape == a["passive"].shape == (20, 1, 800)
    assert np.isfinite(a["readings"]).all() and np.isfinite(a["passive"]).all()
    # before contact the heated channel sits at its set point, drifting at 0.1 K/s
    t = np.arange(800) / 100.0
    pre = t < 2.4
    drift = np.polyfit(t[pre], a["readings"][0, 0, pre], 1)[0]
    assert drift == pytest.approx(0.1, abs=0.01)
    assert TASK.input_shape(scene) == (2, 600)  # type: ignore[arg-type]
    heated = dataclasses.replace(scene, sensor=replace(scene.sensor, "channels", ["heated"]))  # type: ignore[attr-defined]
    assert TASK.input_shape(heated) == (600,)


def test_passive_channel_stays_flat_on_an_object_at_its_temperature() -> None:
    """No temperature difference, no drift: nothing flows, the passive reading does not move."""
    scene = robot_scene(**{"objects.offset_k": [0.0, 0.0], "sensor.drift_k_s": [0.0, 0.0]})
    a = make_simulator(dataclasses.replace(scene, noise=False)).simulate(4, np.random.default_rng(0))  # type: ignore[arg-type]
    assert np.ptp(a["passive"]) < 1e-9
    assert np.ptp(a["readings"]) > 0.5  # the heated one is 7 K above it and drops


def test_a_four_by_four_array_with_passive_channels_and_warm_objects() -> None:
    scene = robot_scene(**{"grid": [4, 4], "objects.offset_k": [3.0, 8.0], "objects.second_object": 0.5})
    a = make_simulator(scene).simulate(5, np.random.default_rng(1))  # type: ignore[arg-type]
    assert a["readings"].shape == (5, 16, 800) and a["passive"].shape == (5, 16, 800)
    touched = a["latent_class"] >= 0
    # a warm object heats the passive thermistor
    assert (a["passive"][touched][:, -1] > a["passive"][touched][:, 0]).all()


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("channels", ["heated", "passive", "passive"], "name each channel once"),
        ("contact.contact_s", [1.0, 1.0], "contact_s must reach"),
        ("sensor.controller_kp", [10.0, 10.0], "gains need heater = 'held'"),
        ("objects.classes", [{"name": "metal", "materials": ["unobtainium"]}], "unknown label 'unobtainium'"),
    ],
)
def test_real_sensor_config_errors_name_the_problem(key: str, value: object, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        robot_scene(**{key: value})
    with pytest.raises(ConfigError, match=r"needs passive\.enabled"):
        robot_scene(**{"passive.enabled": False})


def test_press_onset_reads_half_the_plateau_through_dropouts() -> None:
    t = np.arange(0, 8, 0.005)
    force = np.where(t < 0.8, 0.0, np.minimum(1.0 + (t - 0.8) * 8.0, 4.8))
    force[(t > 0.4) & (t < 0.8) & (np.arange(len(t)) % 3 == 0)] = 1.0  # toggling in the dead band
    force[(t > 3.0) & (t < 3.02)] = 0.0  # a dropout in the plateau
    onset = press_onset(t, force)
    assert onset == pytest.approx(0.8 + (2.4 - 1.0) / 8.0, abs=0.01)
    assert press_onset(t, np.zeros_like(t)) is None  # no press
    assert press_onset(t, np.full_like(t, 3.0)) is None  # pressed before the record started


def test_multichannel_recordings_round_trip_and_labels(tmp_path: Path) -> None:
    touches = robot_touches(4, 2)
    write_recordings(tmp_path / "rec", touches)
    back = read_recordings(tmp_path / "rec")
    assert [t.material for t in back] == [t.material for t in touches]
    for a, b in zip(touches, back, strict=True):
        assert b.passive_c is not None and b.force is not None
        assert np.allclose(a.passive_c, b.passive_c, atol=1e-5) and np.allclose(a.force, b.force, atol=1e-5)  # type: ignore[arg-type]
    # families and a user's classes are labels too; an unknown one lists what is accepted
    index = (tmp_path / "rec" / "touches.csv").read_text().replace("metal", "wood")
    (tmp_path / "rec" / "touches.csv").write_text(index.replace("oak", "wood"))
    assert {t.material for t in read_recordings(tmp_path / "rec")} == {"wood"}
    (tmp_path / "rec" / "touches.csv").write_text(index.replace("wood", "balsa", 1))
    with pytest.raises(DataError, match=r"unknown label 'balsa' .*families: metal"):
        read_recordings(tmp_path / "rec")
    classes = tmp_path / "classes.toml"
    classes.write_text('[classes]\nbalsa = ["wood"]\n')
    assert main(["materials", "--classes", str(classes)]) == 0
    assert main(["materials", "--label", "wood"]) == 0


def test_eval_on_recordings_uses_the_force_onset_durations_and_groups(tmp_path: Path) -> None:
    touches = robot_touches(6, 4)
    write_recordings(tmp_path / "rec", touches)
    scene = robot_scene()
    data = TASK.load_eval_data(tmp_path / "rec", scene)  # type: ignore[arg-type]
    assert set(data.extra["onset_from"]) == {"force"}
    # the onset read from the force: PRESS_LEAD_S after the thermal contact (to a sample)
    sim = make_simulator(scene).simulate(6, np.random.default_rng(4))  # type: ignore[arg-type]
    assert np.allclose(data.extra["onset_s"], sim["latent_onset_s"][:, 0] + PRESS_LEAD_S, atol=0.02)
    write_scene(scene, tmp_path / "robot.toml")  # type: ignore[arg-type]
    out = tmp_path / "r.json"
    args = ["eval", "--task", "thermal", "--data", str(tmp_path / "rec"), "--method", "calibrated"]
    assert (
        main(
            [
                *args,
                "--scene",
                str(tmp_path / "robot.toml"),
                "--durations",
                "1,3",
                "--group-by",
                "condition",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    result = json.loads(out.read_text())["metrics"]
    assert set(result["accuracy_by_duration"]) == {"1.0", "3.0"}
    assert set(result["by_group"]) <= {"cold", "room"} and result["by_group"]
    assert result["accuracy_by_duration"]["3.0"] >= 5 / 6  # the exact model on its own touches
    assert main([*args, "--scene", str(tmp_path / "robot.toml"), "--group-by", "nope"]) == 2


def test_calibration_recovers_a_known_sensor_and_reports_itself(tmp_path: Path) -> None:
    """Touches of the robot scene (the model is exact here): the fit explains them within 3 noise
    sigma, recovers the heated channel's heat capacity and lags, and writes a scene that loads."""
    touches = robot_touches(6, 11, robot_scene(**{"objects.offset_k": [-12.0, 1.0]}))
    write_recordings(tmp_path / "rec", touches)
    classes = tmp_path / "classes.toml"
    classes.write_text('[classes]\nmetal = ["aluminium"]\nwood = ["oak"]\n')
    scene, report = calibrate_recordings(tmp_path / "rec", ("heated", "passive"), CLASSES, starts=2)
    assert report["residual"]["rms_sigma"] <= 3.0, report["residual"]
    values = report["parameters"]
    assert values["heated.heat_capacity_j_m2k"]["value"] == pytest.approx(4000.0, rel=0.15)
    assert values["heated.lags_s"]["value"] == pytest.approx(1.3, rel=0.15)
    assert set(report) >= {"at_bound", "not_identified", "noise", "touches", "classes"}
    out = write_scene(scene, tmp_path / "mine.toml", report)
    loaded = load_scene(out)
    assert loaded.sensor.class_names == ("metal", "wood") and loaded.sensor.passive.enabled
    # one class only: a clear error, nothing written
    one = [dataclasses.replace(t, material="wood") for t in touches]
    write_recordings(tmp_path / "one", one)
    with pytest.raises(DataError, match="a classifier needs two or more"):
        calibrate_recordings(tmp_path / "one")


def test_adapt_end_to_end_writes_a_model_with_its_calibration(tmp_path: Path) -> None:
    """A tiny budget: the point is the pipeline (calibrate, generate, train, validate on the labelled
    touches, export, card), not the accuracy; the card says how good it is and warns."""
    from tactile_learn.runtime import OnnxEstimator

    write_recordings(tmp_path / "rec", robot_touches(6, 21))
    out = tmp_path / "adapted"
    args = ["adapt", "--task", "thermal", "--data", str(tmp_path / "rec"), "--out", str(out)]
    assert main([*args, "--channels", "heated", "--n-train", "512", "--epochs", "1", "--starts", "1"]) == 0
    card = json.loads((out / "model.json").read_text())
    assert card["classes"] == ["metal", "wood"] and card["channels"] == ["heated"]
    assert "residual" in card["calibration"] and "parameters" in card["calibration"]
    assert set(card["metrics"]["labelled_touches"]["values"]["accuracy_by_duration"]) >= {"1.0", "2.0"}
    assert isinstance(card["warnings"], list)
    assert load_scene(out / "sensor.toml").sensor.channels == ("heated",)
    model = OnnxEstimator(out / "model.onnx").prepare()
    data = TASK.load_eval_data(tmp_path / "rec", model.card_scene_)
    assert model.predict_proba(data.inputs).shape == (6, 3)  # metal, wood, none
    # the output folder is never overwritten
    assert main([*args, "--channels", "all"]) == 2


def test_heater_modes_change_the_reading_by_the_power_step_alone() -> None:
    """Same touches, heater 'constant' against 'step' (+2000 W/m^2 at 1 s) and 'off' (4000 W/m^2 cut
    at 1 s): identical before the change, then apart by the power-step term (a heater that heats
    more warms the sensor, one switched off lets it cool)."""
    base = dataclasses.replace(robot_scene(), noise=False)
    runs = {}
    for mode, extra in (
        ("constant", {}),
        ("step", {"sensor.heater_step_w_m2": [2000.0, 2000.0], "sensor.heater_off_s": [1.0, 1.0]}),
        ("off", {"sensor.heater_w_m2": [4000.0, 4000.0], "sensor.heater_off_s": [1.0, 1.0]}),
    ):
        config = replace(base.sensor, "sensor.heater", mode)  # type: ignore[attr-defined]
        for key, value in extra.items():
            config = replace(config, key, value)
        scene = dataclasses.replace(base, sensor=config)  # type: ignore[type-var]
        runs[mode] = make_simulator(scene).simulate(3, np.random.default_rng(8))
    onset = runs["constant"]["latent_onset_s"][:, 0]
    t = np.arange(800) / 100.0
    before = t[None, :] < onset[:, None] + 1.0
    for mode, sign in (("step", 1.0), ("off", -1.0)):
        diff = runs[mode]["readings"][:, 0] - runs["constant"]["readings"][:, 0]
        assert np.abs(diff[before]).max() < 1e-5
        assert (sign * diff[:, -1] > 0.1).all()
