"""Calibration of the capacitive array: the fit recovers a device, the front end inverts it."""

from __future__ import annotations

import dataclasses
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from synth.dataset import generate, simulate_shard
from synth.errors import InputError
from synth.io import atomic_save_npz
from synth.scene import Scene, load_scene
from synth.sensors.capacitive.config import CalibrationTable
from synth.sensors.capacitive.physics import device_cells
from synth.sensors.capacitive.sensor import load_noise_n
from tactile_learn.calibration.capacitive import CapacitiveFrontEnd, fit_calibration
from tactile_learn.cli import main
from tactile_learn.estimators.classical.capacitive import BicubicEstimator, DeconvolutionEstimator
from tests.capacitive_scenes import calibration_rig, tiny_capacitive_scene

QUIET = {"drift_v": 0.0, "drift_v_per_frame": 0.0}


def true_table(scene: Scene) -> CalibrationTable:
    config = scene.sensor
    gain, stiffness = device_cells(config)
    return CalibrationTable(
        gain=tuple(gain.ravel().tolist()),
        stiffness=tuple(stiffness.ravel().tolist()),
        crosstalk=config.readout.crosstalk,
        hysteresis_width=config.hysteresis.width,
        play_share=config.hysteresis.play_share,
    )


@cache
def rig_presses(noise: bool) -> tuple[Scene, dict[str, np.ndarray]]:
    scene = tiny_capacitive_scene(device={"seed": 4})
    rig = calibration_rig(scene).with_noise(noise)
    return scene, simulate_shard(rig, 3, 0, 24)  # every one of the 12 cells pressed twice


@pytest.mark.parametrize("noise", [False, True])
def test_fit_recovers_the_devices_parameters(noise: bool) -> None:
    scene, presses = rig_presses(noise)
    table, summary = fit_calibration(presses["readings"], presses["cell_load"], scene.sensor)
    gain, stiffness = device_cells(scene.sensor)
    assert summary["converged"]
    tol = 0.01 if noise else 1e-4  # with noise: the seed's 7 bits over a few presses per cell
    assert np.abs(np.array(table.gain) - gain.ravel()).max() < tol
    assert np.abs(np.array(table.stiffness) - stiffness.ravel()).max() < 3 * tol
    config = scene.sensor
    assert table.crosstalk == pytest.approx(config.readout.crosstalk, abs=tol)
    assert table.hysteresis_width == pytest.approx(config.hysteresis.width, abs=3 * tol)
    # with noise the residual is the noise; without it the fit is exact (rounding only)
    assert summary["rms_residual_v"] < (1.1 * summary["noise_v"] if noise else 1e-5)


def test_front_end_inverts_a_press_with_the_true_device() -> None:
    scene = tiny_capacitive_scene(readout=QUIET).with_noise(False)
    data = simulate_shard(scene, 8, 0, 20)
    table = true_table(scene)
    calibrated = CapacitiveFrontEnd(scene.sensor, calibration=table, drift=False).loads(data["readings"])
    assert np.abs(calibrated - data["cell_load"]).max() < 1e-4
    nominal = CapacitiveFrontEnd(scene.sensor, calibration="nominal", drift=False).loads(data["readings"])
    assert np.abs(nominal - data["cell_load"]).max() > 0.05  # the per-cell gains matter
    static = CapacitiveFrontEnd(scene.sensor, calibration=table, hysteresis=False, drift=False).loads(data["readings"])
    assert np.abs(static - data["cell_load"]).max() > 10 * np.abs(calibrated - data["cell_load"]).max()


def test_stream_equals_the_batch_front_end() -> None:
    scene = tiny_capacitive_scene(readout=QUIET).with_noise(False)
    data = simulate_shard(scene, 2, 0, 3)
    front = CapacitiveFrontEnd(scene.sensor, calibration=true_table(scene))
    batch = front.loads(data["readings"])
    for press in range(3):
        stream = front.stream()
        frames = np.stack([stream.push(f) for f in data["readings"][press]])
        assert np.allclose(frames, batch[press], atol=1e-6)


def test_drift_is_removed_without_bias() -> None:
    probe = {"kinds": [{"kind": "punch", "force_n": [0.3, 1.5], "radius_mm": [0.5, 1.0]}], "margin_mm": 3.0}
    scene = tiny_capacitive_scene(rows=8, cols=8, readout={"drift_v": 0.05, "drift_v_per_frame": 0.005}, stimuli=probe)
    data = simulate_shard(scene, 2, 0, 40)
    idle = data["cell_load"] < 1e-3
    sigma = load_noise_n(scene.sensor)

    def idle_bias(drift: bool) -> np.ndarray:
        loads = CapacitiveFrontEnd(scene.sensor, calibration=true_table(scene), drift=drift).loads(data["readings"])
        err = np.where(idle, loads - data["cell_load"], 0.0)
        return err.sum(axis=(2, 3)) / idle.sum(axis=(2, 3))  # mean error of each frame's idle cells

    # a 50 mV offset is ~14 g on a cell; removed, the idle cells' mean error is a fraction of their noise
    assert abs(idle_bias(True).mean()) < 0.3 * sigma
    assert np.sqrt(np.mean(idle_bias(True) ** 2)) < 0.6 * sigma
    assert np.sqrt(np.mean(idle_bias(False) ** 2)) > 20 * sigma


def test_bad_readings_are_refused() -> None:
    scene = tiny_capacitive_scene()
    front = CapacitiveFrontEnd(scene.sensor)
    good = simulate_shard(scene, 1, 0, 2)["readings"]
    with pytest.raises(InputError, match="expected shape"):
        front.loads(good[0])
    for value, match in ((np.nan, "NaN"), (-0.1, "negative"), (scene.sensor.readout.full_scale_v, "saturated")):
        bad = good.copy()
        bad[1, 2, 0, 1] = value
        with pytest.raises(InputError, match=match):
            front.loads(bad)


def test_calibrate_command_writes_a_scene_that_loads(workdir: Path) -> None:
    scene, _ = rig_presses(True)
    rig = calibration_rig(scene)
    generate(rig, 24, 3, workdir / "rig")
    (workdir / "device.toml").write_text("")  # the target scene: written as a file for the CLI
    from synth.config import dumps_toml

    (workdir / "device.toml").write_text(dumps_toml(scene.to_dict()))
    assert (
        main(["calibrate", "--task", "capacitive", "--data", "rig", "--scene", "device.toml", "--out", "cal.toml"]) == 0
    )
    calibrated = load_scene(workdir / "cal.toml")
    assert calibrated.name == "cal" and calibrated.sensor.calibration is not None
    gain, _ = device_cells(scene.sensor)
    assert np.abs(np.array(calibrated.sensor.calibration.gain) - gain.ravel()).max() < 0.01
    # the simulation is the device's, whatever the table says: same readings as the target scene
    assert np.array_equal(simulate_shard(calibrated, 1, 0, 3)["readings"], simulate_shard(scene, 1, 0, 3)["readings"])


def test_calibrate_refuses_another_device_and_incomplete_presses(workdir: Path, capsys: pytest.CaptureFixture) -> None:
    scene, presses = rig_presses(True)
    other = dataclasses.replace(
        scene, sensor=dataclasses.replace(scene.sensor, device=dataclasses.replace(scene.sensor.device, seed=99))
    )
    generate(calibration_rig(other), 24, 3, workdir / "other")
    from synth.config import dumps_toml

    (workdir / "device.toml").write_text(dumps_toml(scene.to_dict()))
    args = ["calibrate", "--task", "capacitive", "--scene", "device.toml", "--out", "cal.toml", "--data"]
    assert main([*args, "other"]) == 2
    assert "another device" in capsys.readouterr().err
    atomic_save_npz(workdir / "no_loads.npz", {"readings": presses["readings"]})
    assert main([*args, "no_loads.npz"]) == 2
    assert "cell_load" in capsys.readouterr().err
    one_cell = {k: v[:1] for k, v in presses.items()}  # only cell 0 is pressed
    atomic_save_npz(workdir / "one.npz", one_cell)
    assert main([*args, "one.npz"]) == 2
    assert "never loaded" in capsys.readouterr().err
    assert not (workdir / "cal.toml").exists()


@given(
    st.floats(0.0, 1.0),
    st.integers(0, 2**32 - 1),
    st.sampled_from(["scene", "nominal"]),
)
def test_any_reading_within_the_adc_gives_finite_loads_and_images(level: float, seed: int, table: str) -> None:
    scene = load_scene("capacitive8")
    top = scene.sensor.readout.full_scale_v
    rng = np.random.default_rng(seed)
    readings = np.clip(level * top * (1 + 0.5 * rng.standard_normal((2, 3, 8, 8))), 0.0, 0.999 * top)
    loads = CapacitiveFrontEnd(scene.sensor, calibration=table).loads(readings)
    assert np.isfinite(loads).all()
    frames = np.maximum(loads.reshape(-1, 8, 8), -0.1 * scene.sensor.readout.full_scale_n)  # the input floor
    for method in (BicubicEstimator, DeconvolutionEstimator):
        assert np.isfinite(method(scene).fit().predict(frames)).all()
