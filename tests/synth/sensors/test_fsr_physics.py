"""Physics of the FSR film simulator (synth.sensors.fsr): each stage against theory and invariants."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from synth.config import from_dict, replace
from synth.errors import ConfigError
from synth.scene import load_scene, parse_scene
from synth.sensors import fsr

SCENE = load_scene("fsr6")
CONFIG: fsr.FsrConfig = SCENE.sensor


def _scene(**overrides: object) -> object:
    config = CONFIG
    for key, value in overrides.items():
        config = replace(config, key, value)
    return dataclasses.replace(SCENE, sensor=config)


# ---- geometry ----------------------------------------------------------------------------------


def test_layout_is_four_equilateral_triangles_of_the_side() -> None:
    tri = fsr.triangle_vertices(CONFIG.layout)
    sides = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=-1)
    np.testing.assert_allclose(sides, CONFIG.layout.side_mm, rtol=1e-12)
    pos = fsr.sensor_positions(CONFIG.layout)
    np.testing.assert_allclose(pos.mean(axis=0)[0], 0.0, atol=1e-12)  # symmetric about x = 0
    assert np.abs(pos).max() + CONFIG.layout.sensor_diameter_mm / 2 < CONFIG.layout.size_mm / 2


def test_in_triangles_matches_the_big_triangle() -> None:
    pos = fsr.sensor_positions(CONFIG.layout)
    centroids = fsr.triangle_vertices(CONFIG.layout).mean(axis=1)
    assert fsr.in_triangles(centroids, CONFIG.layout).all()
    assert fsr.in_triangles(pos, CONFIG.layout).all()  # vertices belong to the closed triangles
    outside = np.array([[0.0, 30.0], [-30.0, -30.0], [35.0, 0.0], [0.0, -13.0]])
    assert not fsr.in_triangles(outside, CONFIG.layout).any()
    assert fsr.in_triangles(np.array([[0.0, -12.0]]), CONFIG.layout, tol_mm=1.0).all()


# ---- mechanics ---------------------------------------------------------------------------------


@pytest.mark.parametrize("d", [0.0, 3.0, 11.547, 20.0, 45.0, 90.0])
def test_transfer_reduces_to_boussinesq_for_a_point_sensor(d: float) -> None:
    """Tiny disc, point load, no corrections: the Hankel table is the closed-form kernel."""
    b = 0.01
    transfer = fsr._transfer_cached(6.0, b, 1.0, 0.0, 16.0, 116.0, 1.0)
    got = transfer.per_newton(np.array(d), np.array(0.0)) / (math.pi * b * b)
    want = 3 * 6.0**3 / (2 * math.pi * (d * d + 36.0) ** 2.5)
    assert got == pytest.approx(want, rel=5e-4)  # bilinear table, 0.125 mm steps


def test_transfer_of_a_huge_disc_carries_the_whole_load() -> None:
    """A disc much wider than the depth catches every newton (the kernel is normalised)."""
    b = 100.0
    transfer = fsr._transfer_cached(6.0, b, 1.0, 0.0, 16.0, 10.0, 0.5)
    inside = 1.0 - (6.0 / math.hypot(6.0, b)) ** 3  # share of a Boussinesq load within radius b
    assert float(transfer.per_newton(np.array(0.0), np.array(0.3))) == pytest.approx(inside, rel=1e-4)


def test_hertz_spreading_lowers_the_on_axis_load_a_little() -> None:
    transfer = fsr.make_transfer(CONFIG)
    point = float(transfer.per_newton(np.array(0.0), np.array(0.0)))
    spread = float(transfer.per_newton(np.array(0.0), np.array(2.0)))
    assert spread < point
    assert spread > 0.9 * point  # a 2 mm contact radius barely matters 6 mm down


def test_hertz_radius_formula() -> None:
    lay = CONFIG.layout
    e_star = lay.youngs_modulus_mpa / (1 - lay.poisson**2)
    a = fsr.hertz_radius_mm(np.array(5.0), np.array(4.0), lay)
    assert float(a) == pytest.approx((3 * 5.0 * 4.0 / (4 * e_star)) ** (1 / 3))


def test_discs_never_carry_more_than_the_applied_load() -> None:
    grid = np.stack(np.meshgrid(np.linspace(-39, 39, 53), np.linspace(-39, 39, 53)), -1).reshape(-1, 2)
    for tip in CONFIG.stimulus.tip_radii_mm:
        loads = fsr.sensor_loads(CONFIG, grid, np.full(len(grid), 10.0), np.full(len(grid), tip))
        assert loads.min() >= 0.0
        assert loads.sum(axis=1).max() < 10.0


def test_pure_half_space_puts_a_centroid_load_below_the_break_force() -> None:
    """The issue's magnitude check: 10 N at a triangle's centre, pure half-space, ~0.06 N per disc."""
    config = replace(replace(CONFIG, "transfer.layer_gain", 1.0), "transfer.share_gain", 0.0)
    centroid = fsr.triangle_vertices(config.layout)[3].mean(axis=0)
    loads = fsr.sensor_loads(config, centroid[None], np.array([10.0]), np.array([4.0]))[0]
    assert loads[[3, 4, 5]] == pytest.approx([0.06] * 3, rel=0.05)
    assert loads.max() < config.element.break_force_n
    # the calibrated film carries it: every sensor of the triangle is well above the break force
    calibrated = fsr.sensor_loads(CONFIG, centroid[None], np.array([10.0]), np.array([4.0]))[0]
    assert calibrated[[3, 4, 5]].min() > 5 * CONFIG.element.break_force_n


# ---- FSR law and readout ----------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(load=st.floats(0.12, 40.0), gain=st.floats(0.9, 1.1))
def test_fsr_law_inverts(load: float, gain: float) -> None:
    law = fsr.FsrLaw(CONFIG.element)
    g = law.conductance_us(np.array(load), gain)
    assert float(law.load_from_conductance(g, gain)) == pytest.approx(load, rel=1e-3)


def test_fsr_law_shape() -> None:
    law = fsr.FsrLaw(CONFIG.element)
    c = CONFIG.element
    loads = np.geomspace(1e-3, 50.0, 2000)
    g = law.conductance_us(loads)
    assert np.all(np.diff(g) > 0)  # monotone
    assert g[loads < 0.5 * c.break_force_n].max() < 2 * c.leak_conductance_us  # off below the break
    mid = (loads > 0.3) & (loads < 1.0)  # proportional to force above the break (R ~ 1/F)
    np.testing.assert_allclose(g[mid] / loads[mid], c.conductance_us_per_n, rtol=0.02)
    assert g[-1] < c.conductance_us_per_n * c.saturation_force_n + c.leak_conductance_us  # soft saturation


@settings(max_examples=60, deadline=None)
@given(code=st.floats(0.0, 1022.0))
def test_readout_round_trip(code: float) -> None:
    readout = fsr.Readout(CONFIG.readout)
    g = readout.conductance_us(np.array(code))
    assert float(readout.codes(g, quantise=False)) == pytest.approx(code, abs=1e-6)


def test_readings_never_reach_full_scale() -> None:
    """The FSR's saturation keeps the divider below the ADC's full scale (which check_inputs refuses)."""
    sim = fsr.make_simulator(SCENE)
    pos = fsr.sensor_positions(CONFIG.layout)
    worst = sim.forward(pos, np.full(6, CONFIG.stimulus.force_range_n[1] * 2), 2.0, gains=1.2)
    assert worst.max() < sim.readout.full_scale


@settings(max_examples=40, deadline=None)
@given(
    x=st.floats(-39.0, 39.0),
    y=st.floats(-39.0, 39.0),
    f=st.lists(st.floats(0.1, 10.0), min_size=2, max_size=6),
    tip=st.sampled_from(CONFIG.stimulus.tip_radii_mm),
)
def test_readings_monotone_in_force(x: float, y: float, f: list[float], tip: float) -> None:
    sim = fsr.make_simulator(SCENE)
    forces = np.sort(np.asarray(f))
    clean = sim.forward(np.tile([x, y], (len(forces), 1)), forces, tip, quantise=False)
    assert np.all(np.diff(clean, axis=0) >= -1e-9)
    quantised = sim.forward(np.tile([x, y], (len(forces), 1)), forces, tip)
    assert np.all(np.diff(quantised, axis=0) >= 0)


# ---- simulator ---------------------------------------------------------------------------------


def test_outputs_follow_the_scene() -> None:
    for outputs in (("readings",), ("truth",), ("readings", "truth", "latent", "sensor_force")):
        scene = SCENE.with_outputs(outputs)
        sim = fsr.make_simulator(scene)
        specs = sim.output_specs()
        arrays = sim.simulate(300, np.random.default_rng(0))
        assert set(arrays) == set(specs)
        for key, spec in specs.items():
            assert arrays[key].shape == (300, *spec.shape), key
            assert arrays[key].dtype == np.dtype(spec.dtype), key


def test_simulate_is_deterministic_and_the_stream_ignores_outputs() -> None:
    full = fsr.make_simulator(SCENE).simulate(500, np.random.default_rng(7))
    again = fsr.make_simulator(SCENE).simulate(500, np.random.default_rng(7))
    only = fsr.make_simulator(SCENE.with_outputs(("readings",))).simulate(500, np.random.default_rng(7))
    for key in full:
        np.testing.assert_array_equal(full[key], again[key])
    np.testing.assert_array_equal(full["readings"], only["readings"])


def test_latents_are_consistent() -> None:
    arrays = fsr.make_simulator(SCENE.with_outputs(("readings", "truth", "latent", "sensor_force"))).simulate(
        2000, np.random.default_rng(3)
    )
    contact = arrays["latent_contact"]
    assert 0.05 < 1 - contact.mean() < 0.15  # no_contact_fraction = 0.1
    assert np.all(arrays["force_n"][~contact] == 0) and np.all(arrays["force_n"][contact] > 0)
    lo, hi = CONFIG.stimulus.force_range_n
    assert arrays["force_n"][contact].min() >= lo * (1 - 1e-6) and arrays["force_n"].max() <= hi * (1 + 1e-6)
    half = CONFIG.layout.size_mm / 2
    assert np.abs(arrays["xy_mm"]).max() <= half
    inside = fsr.in_triangles(arrays["xy_mm"][contact].astype(np.float64), CONFIG.layout, tol_mm=1e-3)
    assert 0.45 < inside.mean() < 0.65  # half drawn inside, plus whole-film draws that land inside
    # film gains are a pure function of the film id, frames_per_film frames per film
    ids = arrays["latent_film_id"]
    for film_id in np.unique(ids)[:5]:
        rows = ids == film_id
        np.testing.assert_allclose(
            arrays["latent_gain"][rows],
            fsr.film_gains(int(film_id), CONFIG.film)[None].repeat(rows.sum(), 0),
            rtol=1e-6,
        )
    assert len(np.unique(ids)) == math.ceil(2000 / CONFIG.film.frames_per_film)
    spread = np.abs(arrays["latent_gain"] - 1).max()
    assert 0.03 < spread <= CONFIG.film.gain_spread + 1e-6
    rep = np.abs(arrays["latent_press_gain"] / arrays["latent_gain"] - 1).max()
    assert 0.01 < rep <= CONFIG.film.repeatability + 1e-6
    # noise-free loads reproduce the readings through the law and readout (up to ADC noise)
    sim = fsr.make_simulator(SCENE)
    law_codes = sim.readout.codes(
        sim.law.conductance_us(arrays["sensor_force_n"].astype(np.float64), arrays["latent_press_gain"])
    )
    assert np.abs(law_codes - arrays["readings"]).max() <= 4  # 0.7 LSB rms noise, 3e4 draws


def test_other_seeds_hold_other_films() -> None:
    a = fsr.make_simulator(SCENE).simulate(1024, np.random.default_rng(1))
    b = fsr.make_simulator(SCENE).simulate(1024, np.random.default_rng(2))
    assert not set(a["latent_film_id"].tolist()) & set(b["latent_film_id"].tolist())


def test_noise_off_gives_the_nominal_film_exactly() -> None:
    scene = SCENE.with_noise(False)
    arrays = fsr.make_simulator(scene.with_outputs(("readings", "truth", "latent"))).simulate(
        400, np.random.default_rng(5)
    )
    np.testing.assert_array_equal(arrays["latent_gain"], 1.0)
    sim = fsr.make_simulator(scene)
    expected = sim.forward(
        arrays["xy_mm"],
        arrays["force_n"],
        np.where(arrays["latent_tip_radius_mm"] > 0, arrays["latent_tip_radius_mm"], 1.0),
    )
    np.testing.assert_array_equal(arrays["readings"], expected.astype(np.float32))


def test_a_calibrated_film_scene_uses_its_gains() -> None:
    gains = (1.05, 0.95, 1.0, 1.02, 0.98, 1.01)
    scene = _scene(**{"film.gains": list(gains)})
    arrays = fsr.make_simulator(scene).simulate(200, np.random.default_rng(0))
    np.testing.assert_allclose(arrays["latent_gain"], np.tile(gains, (200, 1)), rtol=1e-6)


# ---- configuration -----------------------------------------------------------------------------


def test_scene_validation_names_the_key() -> None:
    data = SCENE.to_dict()
    data["fsr"]["film"].pop("gains")
    parse_scene(data)  # round trip of the shipped scene
    bad = SCENE.to_dict()
    bad["fsr"]["film"].pop("gains")
    bad["fsr"]["readout"]["adc_bits"] = 12
    with pytest.raises(ConfigError, match=r"readout\.adc_bits"):
        parse_scene(bad)
    with pytest.raises(ConfigError, match="sensor_depth_mm"):
        from_dict(fsr.FsrConfig, {"layout": {"sensor_depth_mm": 9.0}})
    with pytest.raises(ConfigError, match="gains"):
        from_dict(fsr.FsrConfig, {"film": {"gains": [1.0, 1.0]}})
    with pytest.raises(ConfigError, match=r"stimulus\.wobble"):
        from_dict(fsr.FsrConfig, {"stimulus": {"wobble": 1}})
    with pytest.raises(ConfigError, match="force_range_n"):
        from_dict(fsr.FsrConfig, {"stimulus": {"force_range_n": [5.0, 1.0]}})
    with pytest.raises(ConfigError, match="side_mm"):
        from_dict(fsr.FsrConfig, {"layout": {"side_mm": 40.0}})
