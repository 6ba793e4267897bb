"""Physics properties of the strip-array simulator (noise off unless stated)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import integrate, signal

from synth.mechanics import boussinesq_cell_kernel, rectangle_stress, separable_kernel
from synth.scene import Scene, load_scene
from synth.sensors import sensor_module
from synth.sensors.strips import StripSensor, StripSimulator
from tests.conftest import tiny_strips_scene


def sphere_field(sensor: StripSensor, x_mm: float, y_mm: float, force_n: float, radius_mm: float = 5.0) -> np.ndarray:
    """Hertz field on the sensor's lattice, computed independently of synth.stimuli."""
    ny, nx = sensor.field_shape
    h = sensor.field_pitch_mm
    e_star = sensor.config.layers.e_star_mpa
    a = (3 * force_n * radius_mm / (4 * e_star)) ** (1 / 3)
    p0 = 3 * force_n / (2 * np.pi * a * a) * 1000
    y, x = np.meshgrid((np.arange(ny) + 0.5) * h, (np.arange(nx) + 0.5) * h, indexing="ij")
    return (p0 * np.sqrt(np.clip(1 - ((x - x_mm) ** 2 + (y - y_mm) ** 2) / a**2, 0, None)))[None]


def test_cell_kernel_matches_numerical_integral_of_boussinesq() -> None:
    h, z = 0.625, 1.0
    kernel = boussinesq_cell_kernel(h, z, 4)

    def point(yy: float, xx: float, dy: float, dx: float) -> float:
        r2 = (dx - xx) ** 2 + (dy - yy) ** 2
        return 3 * z**3 / (2 * np.pi * (r2 + z * z) ** 2.5)

    for iy, ix in [(4, 4), (4, 6), (1, 7), (0, 0)]:
        dy, dx = (iy - 4) * h, (ix - 4) * h
        value, _ = integrate.dblquad(
            lambda yy, xx, dy=dy, dx=dx: point(yy, xx, dy, dx), -h / 2, h / 2, -h / 2, h / 2, epsabs=1e-12
        )
        assert kernel[iy, ix] == pytest.approx(value, rel=1e-7)
    # a uniform load over the whole plane transmits exactly its pressure
    assert boussinesq_cell_kernel(h, z, 400).sum() == pytest.approx(1.0, abs=1e-4)
    assert rectangle_stress(np.array(-1e6), np.array(1e6), np.array(-1e6), np.array(1e6), z) == pytest.approx(1.0)


@pytest.mark.parametrize("z", [0.1, 1.0, 2.5])
def test_separable_kernel_meets_its_tolerance(z: float) -> None:
    sep = separable_kernel(0.5, z, 30, rank_tol=1e-4)
    dense = boussinesq_cell_kernel(0.5, z, 30)
    assert np.linalg.norm(sep.dense() - dense) / np.linalg.norm(dense) <= 1e-4
    assert sep.rank <= 8


def brute_force_segment_stress(sensor: StripSensor, field: np.ndarray, depth: float, layer: str) -> np.ndarray:
    """Dense 2-D convolution with the exact cell kernel, then explicit segment averages."""
    cfg = sensor.config.geometry
    h, s = sensor.field_pitch_mm, cfg.samples_per_pitch
    ny, nx = sensor.field_shape
    kernel = boussinesq_cell_kernel(h, depth, max(ny, nx))
    stress = signal.convolve2d(field[0].astype(np.float64), kernel, mode="same")
    out = np.zeros((cfg.n_rows, cfg.n_cols))
    centres = (np.arange(ny) + 0.5) * h
    for i in range(cfg.n_rows):
        for j in range(cfg.n_cols):
            if layer == "row":  # across row i's band, along segment j
                lo = i * cfg.pitch_mm + (cfg.pitch_mm - cfg.strip_width_mm) / 2
                edges = np.arange(ny + 1) * h
                w = np.clip(np.minimum(edges[1:], lo + cfg.strip_width_mm) - np.maximum(edges[:-1], lo), 0, None)
                out[i, j] = (w / w.sum()) @ stress[:, j * s : (j + 1) * s].mean(axis=1)
            else:
                lo = j * cfg.pitch_mm + (cfg.pitch_mm - cfg.strip_width_mm) / 2
                edges = np.arange(nx + 1) * h
                w = np.clip(np.minimum(edges[1:], lo + cfg.strip_width_mm) - np.maximum(edges[:-1], lo), 0, None)
                out[i, j] = stress[i * s : (i + 1) * s, :].mean(axis=0) @ (w / w.sum())
    del centres
    return out


def test_segment_stress_equals_brute_force_convolution(tiny_scene: Scene, rng: np.random.Generator) -> None:
    sensor = StripSensor(tiny_scene.sensor)
    field = rng.random((1, *sensor.field_shape)) * 100
    field[:, :, :5] = 0  # some structure
    row, col = sensor.array.segment_stress(field)
    layers = tiny_scene.sensor.layers
    ref_row = brute_force_segment_stress(sensor, field, layers.cover_mm, "row")
    ref_col = brute_force_segment_stress(sensor, field, layers.cover_mm + layers.strip_thickness_mm, "col")
    assert np.allclose(row[0], ref_row, rtol=2e-3, atol=1e-3 * field.max())
    assert np.allclose(col[0], ref_col, rtol=2e-3, atol=1e-3 * field.max())


def test_stress_is_linear_in_pressure(tiny_scene: Scene, rng: np.random.Generator) -> None:
    array = StripSensor(tiny_scene.sensor).array
    p1, p2 = rng.random((2, 1, *array.field_shape)) * 50
    a, b = 0.7, 2.5
    combined = array.segment_stress(a * p1 + b * p2)
    for layer in range(2):
        expected = a * array.segment_stress(p1)[layer] + b * array.segment_stress(p2)[layer]
        assert np.allclose(combined[layer], expected, rtol=1e-4, atol=1e-4)


def test_readings_follow_the_documented_chain(tiny_scene: Scene, rng: np.random.Generator) -> None:
    """Readings = offset + G (divider(R) - divider(R0)), R = R0 (1 - mean f), f = 1 - (1 + p/g p0)^-n."""
    cfg = tiny_scene.sensor
    sensor = StripSensor(cfg)
    field = sphere_field(sensor, 6.0, 9.0, 2.0)
    gains = 1 + 0.05 * rng.standard_normal((1, 11))
    out = sensor.forward(field, gains=gains)
    row, col = sensor.array.segment_stress(field)
    n = cfg.piezo.exponent
    f_row = 1 - (1 + row[0] / (cfg.piezo.p0_kpa * gains[0, :6, None])) ** -n
    f_col = 1 - (1 + col[0] / (cfg.piezo.p0_kpa * gains[0, None, 6:])) ** -n
    r = cfg.piezo.strip_resistance_ohm * (1 - np.concatenate([f_row.mean(1), f_col.mean(0)]))
    rc = cfg.readout

    def divider(res: np.ndarray) -> np.ndarray:
        return rc.supply_v * rc.reference_ohm / (rc.reference_ohm + res)

    expected = rc.offset_v + rc.amplifier_gain * (divider(r) - divider(np.float64(cfg.piezo.strip_resistance_ohm)))
    assert np.allclose(out["readings"][0], expected, atol=1e-5)
    # and the readout inverse recovers the loads (sum of f along each strip) at unit gain
    unit = sensor.forward(field)
    loads = sensor.invert_readings(unit["readings"])
    f_row = 1 - (1 + row[0] / cfg.piezo.p0_kpa) ** -n
    f_col = 1 - (1 + col[0] / cfg.piezo.p0_kpa) ** -n
    assert np.allclose(loads[0], np.concatenate([f_row.sum(1), f_col.sum(0)]), atol=1e-4)


def test_zero_load_gives_baseline_readings(tiny_scene: Scene, rng: np.random.Generator) -> None:
    sensor = StripSensor(tiny_scene.sensor)
    out = sensor.forward(np.zeros((3, *sensor.field_shape)), gains=1 + 0.1 * rng.random((3, 11)))
    assert np.array_equal(out["readings"], np.full((3, 11), np.float32(tiny_scene.sensor.readout.offset_v)))
    assert not out["pressure"].any()
    noisy = sensor.forward(np.zeros((2000, *sensor.field_shape)), rng=rng, noise=True)["readings"]
    assert abs(noisy.mean() - tiny_scene.sensor.readout.offset_v) < 2e-4
    assert noisy.std() == pytest.approx(
        np.hypot(tiny_scene.sensor.readout.noise_v, tiny_scene.sensor.readout.lsb_v / 12**0.5), rel=0.1
    )


def test_readings_are_monotone_in_force() -> None:
    sensor = StripSensor(load_scene("strips16").sensor)
    forces = np.linspace(0.0, 20.0, 30)
    fields = np.concatenate([sphere_field(sensor, 13.3, 22.1, f) if f > 0 else np.zeros((1, 64, 64)) for f in forces])
    readings = sensor.forward(fields)["readings"]
    assert (np.diff(readings, axis=0) >= -1e-6).all()
    assert (readings[-1] > readings[0]).any()


def test_centred_contact_is_symmetric_and_mirrors_reverse_readings() -> None:
    sensor = StripSensor(load_scene("strips16").sensor)
    centre = 16 * 2.5 / 2
    readings = sensor.forward(sphere_field(sensor, centre, centre, 3.0))["readings"][0]
    rows, cols = readings[:16], readings[16:]
    assert np.allclose(rows, rows[::-1], atol=1e-6)
    assert np.allclose(cols, cols[::-1], atol=1e-6)
    # columns lie deeper than rows: the same contact's stress spreads wider over them
    row_stress, col_stress = sensor.array.segment_stress(sphere_field(sensor, centre, centre, 3.0))
    row_profile, col_profile = row_stress[0].sum(axis=1), col_stress[0].sum(axis=0)
    assert col_profile[6] / col_profile[7] > row_profile[6] / row_profile[7]
    assert col_profile.sum() == pytest.approx(row_profile.sum(), rel=0.02)  # and carries the same load
    a = sensor.forward(sphere_field(sensor, 11.0, 27.0, 2.0))["readings"][0]
    b = sensor.forward(sphere_field(sensor, 40 - 11.0, 27.0, 2.0))["readings"][0]
    assert np.allclose(a[:16], b[:16], atol=1e-6)  # mirroring x keeps rows
    assert np.allclose(a[16:], b[16:][::-1], atol=1e-6)  # and reverses columns


@pytest.mark.parametrize("kind", ["sphere", "punch", "block", "edge"])
def test_windowed_simulation_matches_the_full_field_forward(kind: str) -> None:
    # footprints stay inside the array: the user-field path only sees the array's own lattice
    spec = {
        "kind": kind,
        "force_n": [0.2, 6.0],
        "radius_mm": [0.5, 3.0],
        "width_mm": [0.3, 3.0],
        "length_mm": [1.0, 4.0],
    }
    scene = tiny_strips_scene(kinds=[spec], count=[0, 3], margin_mm=3.0).with_noise(False)
    scene = scene.with_outputs(("readings", "pressure", "field", "latent"))
    sim = StripSimulator(scene)
    out = sim.simulate(64, np.random.default_rng(5))
    again = sim.sensor.forward(out["field"], gains=out["latent_strip_gain"])
    assert np.allclose(out["readings"], again["readings"], atol=2e-5)
    assert np.allclose(out["pressure"], again["pressure"], rtol=1e-4, atol=1e-3)
    assert (out["pressure"] >= 0).all() and np.isfinite(out["readings"]).all()


@pytest.mark.parametrize("cover_mm", [0.3, 0.5, 2.0])
def test_windowed_path_holds_when_the_two_layers_need_different_kernel_ranks(cover_mm: float) -> None:
    # rows lie under the cover, columns a strip thickness deeper: a thin cover gives the two
    # depths separable kernels of different rank (found by a design sweep: 0.5 mm on 4 x 4 strips)
    from synth.scene import parse_scene

    data = tiny_strips_scene(count=[1, 2], margin_mm=3.0).to_dict()
    data["strips"]["layers"]["cover_mm"] = cover_mm
    scene = parse_scene(data, "thin").with_noise(False).with_outputs(("readings", "pressure", "field", "latent"))
    sim = StripSimulator(scene)
    out = sim.simulate(16, np.random.default_rng(1))
    again = sim.sensor.forward(out["field"], gains=out["latent_strip_gain"])
    assert np.allclose(out["readings"], again["readings"], atol=2e-5)


def test_contacts_beyond_the_border_still_load_the_edge_strips() -> None:
    spec = {"kind": "sphere", "force_n": [3.0, 3.0], "radius_mm": [4.0, 4.0]}
    scene = tiny_strips_scene(kinds=[spec], count=[1, 1], margin_mm=-2.0).with_noise(False)
    out = StripSimulator(scene).simulate(200, np.random.default_rng(2))
    xy = out["latent_xy_mm"][:, 0]
    outside = (xy[:, 0] < 0) | (xy[:, 0] > 12.5) | (xy[:, 1] < 0) | (xy[:, 1] > 15.0)
    assert outside.any()
    # the part of the footprint beyond the edge is not in the map, but the strips feel it
    assert (out["readings"][outside].max(axis=1) > scene.sensor.readout.offset_v + 1e-3).all()
    assert np.isfinite(out["readings"]).all() and (out["pressure"] >= 0).all()


@pytest.mark.parametrize("kind", ["sphere", "punch", "block", "edge"])
def test_every_kind_conserves_force_even_when_tiny(kind: str) -> None:
    spec = {
        "kind": kind,
        "force_n": [0.1, 5.0],
        "radius_mm": [0.01, 4.0],
        "width_mm": [0.01, 3.0],
        "length_mm": [0.05, 6.0],
    }
    scene = tiny_strips_scene(kinds=[spec], count=[1, 2], margin_mm=6.0).with_outputs(("field", "latent"))
    sim = StripSimulator(scene)
    out = sim.simulate(40, np.random.default_rng(9))
    carried = out["field"].sum(axis=(1, 2)) * sim.sensor.field_pitch_mm**2 / 1000
    assert np.allclose(carried, out["latent_force_n"].sum(axis=1), rtol=1e-4)


def test_no_contact_frames_short_circuit_and_unwanted_work_is_skipped() -> None:
    scene = tiny_strips_scene(empty_fraction=1.0).with_noise(False)
    out = StripSimulator(scene).simulate(10, np.random.default_rng(0))
    assert not out["pressure"].any()
    assert np.array_equal(out["readings"], np.full_like(out["readings"], np.float32(scene.sensor.readout.offset_v)))
    latent_only = StripSimulator(tiny_strips_scene().with_outputs(("latent",)))
    arrays = latent_only.simulate(10, np.random.default_rng(0))
    assert "sensor" not in latent_only.__dict__  # the mechanics operators were never built
    assert "readings" not in arrays and "latent_xy_mm" in arrays


def test_simulation_is_deterministic_and_independent_of_outputs() -> None:
    scene = load_scene("strips16")
    module = sensor_module("strips")
    full = module.make_simulator(scene).simulate(50, np.random.default_rng(3))
    again = module.make_simulator(scene).simulate(50, np.random.default_rng(3))
    readings_only = module.make_simulator(scene.with_outputs(("readings",))).simulate(50, np.random.default_rng(3))
    for key in full:
        assert np.array_equal(full[key], again[key]), key
    assert np.array_equal(full["readings"], readings_only["readings"])


def test_twin_frames_have_identical_contacts() -> None:
    scene = load_scene("strips16")
    data = scene.to_dict()
    data["strips"]["stimuli"]["twin_fraction"] = 1.0
    from synth.scene import parse_scene

    out = StripSimulator(parse_scene(data)).simulate(20, np.random.default_rng(1))
    assert out["latent_twin"].all()
    assert np.array_equal(out["latent_force_n"][:, 0], out["latent_force_n"][:, 1])
    assert not np.array_equal(out["latent_xy_mm"][:, 0], out["latent_xy_mm"][:, 1])


@pytest.mark.parametrize("kind", ["sphere", "edge"])
def test_vanishing_hertz_widths_fall_back_to_a_point_load_without_warnings(kind: str) -> None:
    """Zero or denormal forces give a zero Hertz width: no 0/0, the force still lands in the window."""
    from synth.stimuli import ContactBatch, rasterize

    force = np.array([0.0, 1e-300, 5e-324, 1e-12, 1.0])
    n = len(force)
    contacts = ContactBatch(
        x_mm=np.full(n, 3.3),
        y_mm=np.full(n, 4.1),
        force_n=force,
        radius_mm=np.full(n, 2.0),
        width_mm=np.full(n, 1.0),
        length_mm=np.full(n, 3.0),
        angle_deg=np.full(n, 30.0),
    )
    h = 0.5
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        windows = rasterize(kind, contacts, h, 24, 0.5)
    assert np.isfinite(windows.values).all() and (windows.values >= 0).all()
    carried = windows.values.sum(axis=(1, 2)) * h * h / 1000
    assert np.allclose(carried, force, rtol=1e-9, atol=0)
