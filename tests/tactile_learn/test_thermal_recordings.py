"""The thermal recording format (touches.csv + one CSV per touch), evaluation on recordings, and
calibration of an unknown sensor from a few labelled touches."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from synth.config import replace
from synth.errors import DataError
from synth.scene import load_scene
from synth.sensors.thermal import make_simulator
from tactile_learn.tasks.thermal import ThermalTask
from tactile_learn.thermal_recordings import Touch, read_recordings, resample, write_recordings

WNS = load_scene("thermal_wns")
TASK = ThermalTask()


def _touches(n: int, seed: int, **sensor: object) -> list[Touch]:
    config = replace(WNS.sensor, "grid", [1, 1])
    for key, value in sensor.items():
        config = replace(config, key, value)
    scene = dataclasses.replace(WNS, sensor=config)
    arrays = make_simulator(scene).simulate(n, np.random.default_rng(seed))
    fs = config.readout.sampling_hz
    names = [m.name for m in config.material_list]
    out = []
    for i in range(n):
        t0 = 10.0 + i  # the logger's clock does not start at 0
        out.append(
            Touch(
                file=f"t{i}.csv",
                time_s=t0 + np.arange(arrays["readings"].shape[-1]) / fs,
                temperature_c=arrays["readings"][i, 0].astype(np.float64),
                material=names[int(arrays["latent_material"][i, 0])],
                onset_s=t0 + float(arrays["latent_onset_s"][i, 0]) if i % 2 else None,
                info={"true_onset_s": f"{float(arrays['latent_onset_s'][i, 0]):.5f}"},
            )
        )
    return out


def test_round_trip_of_the_format(tmp_path: Path) -> None:
    touches = _touches(4, 1)
    write_recordings(tmp_path / "rec", touches)
    back = read_recordings(tmp_path / "rec")
    assert [t.material for t in back] == [t.material for t in touches]
    for a, b in zip(touches, back, strict=True):
        assert np.allclose(a.time_s, b.time_s, atol=1e-6) and np.allclose(a.temperature_c, b.temperature_c, atol=1e-5)
        assert (a.onset_s is None) == (b.onset_s is None)
    values, onset = resample(back[1], 25.0)
    assert len(values) == int((back[1].time_s[-1] - back[1].time_s[0]) * 25.0 + 1e-9) + 1 and onset is not None


def _write(folder: Path, index: str, files: dict[str, str]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "touches.csv").write_text(index)
    for name, text in files.items():
        (folder / name).write_text(text)
    return folder


GOOD = "time_s,temperature_c\n0,30\n0.1,30\n0.2,29.5\n"


@pytest.mark.parametrize(
    ("index", "files", "message"),
    [
        (None, {}, "no touches.csv"),
        ("file\na.csv\n", {"a.csv": GOOD}, "missing column.*material"),
        ("file,material\na.csv,oak\n", {}, "touch file not found"),
        ("file,material\na.csv,oak\n", {"a.csv": ""}, "empty file"),
        ("file,material\na.csv,oak\n", {"a.csv": "time,temp\n0,1\n1,2\n"}, "missing column"),
        (
            "file,material\na.csv,oak\n",
            {"a.csv": "time_s,temperature_c\n0,30\n0.2,30\n0.1,29\n"},
            "row 4: time_s does not increase",
        ),
        (
            "file,material\na.csv,oak\n",
            {"a.csv": "time_s,temperature_c\n0,30\n0.1,nan\n0.2,29\n"},
            "not a finite number",
        ),
        ("file,material\na.csv,oak\n", {"a.csv": "time_s,temperature_c\n0,30\n0.1,warm\n"}, "not a number"),
        (
            "file,material\na.csv,oak\n",
            {"a.csv": "time_s,temperature_c,passive_c\n0,30,22\n0.1,30,-400\n0.2,29,22\n"},
            "row 3: passive_c -400 degC is at or below absolute zero",
        ),
        ("file,material\na.csv,unobtainium\n", {"a.csv": GOOD}, "unknown material 'unobtainium'"),
        ("file,material\na.csv,copper\n", {"a.csv": GOOD}, "not in the scene's list"),
        ("file,material\n", {}, "lists no touches"),
    ],
)
def test_clear_errors(tmp_path: Path, index: str | None, files: dict[str, str], message: str) -> None:
    folder = tmp_path / "rec"
    if index is None:
        folder.mkdir()
    else:
        _write(folder, index, files)
    with pytest.raises(DataError, match=message):
        read_recordings(folder, [m.name for m in WNS.sensor.material_list])


def test_eval_on_recordings_detects_onsets_and_skips_unlabelled(tmp_path: Path) -> None:
    touches = _touches(6, 2)
    touches[0] = dataclasses.replace(touches[0], material=None)
    write_recordings(tmp_path / "rec", touches)
    data = TASK.load_eval_data(tmp_path / "rec", WNS)
    assert len(data) == 6 and not data.extra["labelled"][0] and data.extra["labelled"][1:].all()
    fs = WNS.sensor.readout.sampling_hz
    for i, t in enumerate(touches):
        truth = float(t.info["true_onset_s"])
        if t.onset_s is not None:  # given in touches.csv: used as is
            assert data.extra["onset_s"][i] == pytest.approx(t.onset_s - t.time_s[0], abs=1e-5)
        else:  # detected: within a few samples of the truth
            assert abs(data.extra["onset_s"][i] - truth) <= 3.0 / fs
    m = TASK.evaluate(TASK.classical_methods()["physics_fit"](WNS), data)
    # the default views (0.25 to 4 s of contact); 4 s only where the record reaches that far
    assert set(m["accuracy_by_duration"]) <= {"0.25", "0.5", "1.0", "2.0", "4.0"}
    assert {"0.25", "0.5", "1.0", "2.0"} <= set(m["accuracy_by_duration"])
    assert m["n_contact_by_duration"]["1.0"] == 5
    assert data.inputs.shape == (6, WNS.sensor.window_samples)


def test_calibration_recovers_an_unknown_sensor(tmp_path: Path) -> None:
    """A sensor 25 % lighter, with a 25 % weaker loss and 40 Hz sampling: a few labelled touches
    give its heat capacity and loss back, and the calibrated scene loads for generate."""
    touches = _touches(
        6,
        3,
        **{
            "sensor.heat_capacity_j_m2k": [1500.0, 1500.0],
            "sensor.loss_w_m2k": [190.0, 190.0],
            "sensor.heater_w_m2": [3800.0, 3800.0],
            "sensor.pixel_spread": 0.0,
            "readout.sampling_hz": 40.0,
            "objects.property_spread": 0.3,
        },
    )
    write_recordings(tmp_path / "rec", touches)
    summary = TASK.calibrate(tmp_path / "rec", tmp_path / "mine.toml", WNS)
    assert summary["heat_capacity_j_m2k"] == pytest.approx(1500.0, rel=0.08)
    assert summary["loss_w_m2k"] == pytest.approx(190.0, rel=0.25)
    assert summary["sampling_hz"] == pytest.approx(40.0) and summary["adc_step_k"] == pytest.approx(0.01)
    scene = load_scene(tmp_path / "mine.toml")
    assert scene.sensor.readout.sampling_hz == pytest.approx(40.0)
    lo, hi = scene.sensor.sensor.heat_capacity_j_m2k
    assert lo <= summary["heat_capacity_j_m2k"] <= hi
    arrays = make_simulator(scene).simulate(2, np.random.default_rng(0))  # usable by generate
    assert np.isfinite(arrays["readings"]).all()
    with pytest.raises(DataError, match="no labelled touches"):
        write_recordings(tmp_path / "none", [dataclasses.replace(t, material=None) for t in touches[:2]])
        TASK.calibrate(tmp_path / "none", tmp_path / "x.toml", WNS)


def test_a_model_is_never_read_against_another_scenes_classes(tmp_path: Path) -> None:
    """The shipped thermal_wns model and the full library take the same window but predict other
    classes: resolving it against the library's scene is an error, and ``eval`` on recordings
    (which carry no scene) reads them with the model's own scene."""
    from synth.errors import ModelError
    from tactile_learn.cli import main
    from tactile_learn.methods import resolve_method

    with pytest.raises(ModelError, match="classes of scene 'thermal_wns'"):
        resolve_method("thermal", "thermal_wns", load_scene("thermal"))
    write_recordings(tmp_path / "rec", _touches(6, 4))
    out = tmp_path / "r.json"
    args = ["eval", "--task", "thermal", "--data", str(tmp_path / "rec"), "--method", "thermal_wns"]
    assert main([*args, "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["scene"] == "thermal_wns" and result["n_frames"] == 6
    assert result["metrics"]["accuracy_by_duration"]["2.0"] >= 0.5  # a mislabelled model scores ~0
    assert main([*args, "--scene", "thermal"]) != 0
