"""tactile-learn simulate for every sensor, called through main(argv) like a user would: each
sensor's stimulus from an .npz, noise on and off, and clear errors for missing or misshaped arrays."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from synth.materials import get_material
from synth.scene import load_scene
from synth.sensors.fsr import FsrSimulator
from synth.sensors.strips import StripSensor
from tactile_learn.cli import main


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def simulate(scene: str, capsys: pytest.CaptureFixture[str], *extra: str, **arrays: object) -> dict[str, np.ndarray]:
    np.savez("stimulus.npz", **arrays)  # type: ignore[arg-type]
    code, _, err = run(["simulate", "--scene", scene, "--stimulus", "stimulus.npz", "--out", "o.npz", *extra], capsys)
    assert code == 0, err
    with np.load("o.npz") as out:
        return {k: out[k] for k in out.files}


def test_strips_reads_a_field_as_the_strip_sensor_does(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    field = np.zeros((3, 20, 20), np.float32)  # strips5: 5 x 5 strips, 4 cells per pitch
    field[0, 8:12, 8:12] = 50.0
    field[1, 0:4, 12:20] = 30.0
    out = simulate("strips5", capsys, field_kpa=field)
    expected = StripSensor(load_scene("strips5").sensor).forward(field)
    assert out["readings"].shape == (3, 10) and out["pressure"].shape == (3, 5, 5)
    for key in ("readings", "readings_clean", "pressure"):
        assert np.array_equal(out[key], expected[key])
    assert np.all(out["readings"][2] == out["readings"][2, 0])  # nothing pressed: the baseline everywhere
    noisy = simulate("strips5", capsys, "--noise", "on", "--seed", "4", field_kpa=field)
    again = simulate("strips5", capsys, "--noise", "on", "--seed", "4", field_kpa=field)
    assert np.array_equal(noisy["readings"], again["readings"])
    assert not np.array_equal(noisy["readings"], out["readings"])
    assert np.array_equal(noisy["readings_clean"], out["readings_clean"])


def test_fsr_reads_presses_as_the_film_does(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    xy = np.array([[0.0, 0.0], [-10.0, 5.77], [0.0, 0.0]])
    force = np.array([2.0, 6.0, 0.0])
    out = simulate("fsr6", capsys, xy_mm=xy, force_n=force, tip_radius_mm=4.0)
    film = FsrSimulator(load_scene("fsr6").sensor, ("readings",), noise=False)
    assert out["readings"].shape == (3, 6) and out["readings"].dtype == np.float32
    assert np.array_equal(out["readings"], film.forward(xy, force, 4.0).astype(np.float32))  # clean codes
    assert np.array_equal(out["readings"], np.floor(out["readings"]))
    assert out["sensor_force_n"].shape == (3, 6) and not out["sensor_force_n"][2].any()
    # more force on the same spot: more signal on every disc that feels it
    heavier = simulate("fsr6", capsys, xy_mm=xy, force_n=2 * force, tip_radius_mm=4.0)
    assert np.all(heavier["readings"] >= out["readings"]) and np.any(heavier["readings"] > out["readings"])
    single = simulate("fsr6", capsys, "--noise", "on", xy_mm=xy[1], force_n=6.0, tip_radius_mm=4.0)
    assert single["readings"].shape == (6,)
    assert np.abs(single["readings"] - out["readings"][1]).max() <= 5  # ADC noise of 0.7 LSB


def test_thermal_reads_touches_by_material_or_properties(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    alu, oak = get_material("aluminium"), get_material("oak")
    by_name = simulate("thermal", capsys, object_c=[20.0, 20.0], material=np.array(["aluminium", "oak"]))
    by_props = simulate(
        "thermal",
        capsys,
        object_c=[20.0, 20.0],
        k_w_mk=[alu.k_w_mk, oak.k_w_mk],
        rho_kg_m3=[alu.rho_kg_m3, oak.rho_kg_m3],
        c_j_kgk=[alu.c_j_kgk, oak.c_j_kgk],
    )
    scene = load_scene("thermal")
    p, r = scene.sensor.n_pixels, scene.sensor.readout.n_samples
    assert by_name["readings"].shape == (2, p, r) and by_name["time_s"].shape == (r,)
    assert np.array_equal(by_name["readings"], by_props["readings"])
    onset = float(np.mean(scene.sensor.contact.onset_s))
    before, during = by_name["time_s"] < onset, (by_name["time_s"] > onset + 0.5) & (by_name["time_s"] < onset + 1.5)
    heated = by_name["readings"]
    assert np.ptp(heated[:, :, before]) < 1e-4  # at its steady state before contact
    # aluminium draws heat faster than oak: its pixels cool further
    assert np.all(heated[0][:, during] < heated[1][:, during])
    colder = simulate("thermal", capsys, object_c=[10.0, 10.0], material=np.array(["aluminium", "oak"]))
    assert np.all(colder["readings"][:, :, during] < heated[:, :, during])


def test_capacitive_reads_a_pressed_field(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = load_scene("capacitive8")
    g, frames = scene.sensor.geometry, scene.sensor.stimuli.frames
    hp, wp = g.lattice_shape
    field = np.zeros((2, frames, hp, wp), np.float32)
    field[0, :, hp // 2 - 3 : hp // 2 + 3, wp // 2 - 3 : wp // 2 + 3] = 80.0
    out = simulate("capacitive8", capsys, field_kpa=field)
    assert out["readings"].shape == (2, frames, g.n_rows, g.n_cols)
    assert out["cell_load"].shape == out["readings"].shape and not out["cell_load"][1].any()
    assert out["readings"][0].max() > out["readings"][1].max()
    single = simulate("capacitive8", capsys, field_kpa=field[0])
    assert np.array_equal(single["readings"], out["readings"][0])


@pytest.mark.parametrize(
    ("scene", "arrays", "fragment"),
    [
        ("fsr6", {"xy_mm": np.zeros((2, 2)), "tip_radius_mm": 4.0}, "needs an array 'force_n'"),
        (
            "fsr6",
            {"xy_mm": np.zeros((2, 3)), "force_n": np.ones(2), "tip_radius_mm": 4.0},
            "xy_mm: expected shape (2, 2)",
        ),
        ("fsr6", {"xy_mm": np.zeros((2, 2)), "force_n": -np.ones(2), "tip_radius_mm": 4.0}, "force_n: a negative"),
        ("thermal", {"material": np.array(["oak"])}, "needs an array 'object_c'"),
        ("thermal", {"object_c": [20.0], "material": np.array(["unobtainium"])}, "unobtainium"),
        ("thermal", {"object_c": [20.0, 21.0, 22.0], "k_w_mk": [1.0, 2.0], "rho_kg_m3": 1.0, "c_j_kgk": 1.0}, "k_w_mk"),
        ("thermal", {"object_c": [20.0], "rho_kg_m3": 1.0, "c_j_kgk": 1.0}, "needs an array 'k_w_mk'"),
        ("thermal", {"object_c": [np.nan], "material": np.array(["oak"])}, "object_c: contains NaN"),
        ("strips5", {"gains": np.ones((1, 10))}, "needs an array 'field_kpa' (or 'pressure')"),
        ("strips5", {"field_kpa": np.ones((2, 21, 20))}, "expected shape (B, 20, 20)"),
        ("capacitive8", {"field_kpa": np.ones((2, 3, 4, 4))}, "pressure field: expected shape"),
        ("fingertip", {"field_kpa": np.ones((2, 3, 4, 4))}, "simulate takes a"),
    ],
)
def test_missing_or_misshaped_arrays_are_named(
    scene: str, arrays: dict[str, object], fragment: str, workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    np.savez("bad.npz", **arrays)  # type: ignore[arg-type]
    code, _, err = run(["simulate", "--scene", scene, "--stimulus", "bad.npz", "--out", "o.npz"], capsys)
    assert code == 2, err
    assert fragment in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not Path("o.npz").exists()
