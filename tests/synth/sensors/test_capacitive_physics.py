"""Physics of the capacitive array simulator, stage by stage (noise off unless stated)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy import integrate

from synth.config import replace
from synth.dataset import simulate_shard
from synth.errors import ConfigError, InputError
from synth.scene import parse_scene
from synth.sensors import sensor_module
from synth.sensors.capacitive import CapacitiveModel, Presses, PressGenerator
from synth.sensors.capacitive.config import CapacitiveConfig
from synth.sensors.capacitive.layer import tab_load_operator
from synth.sensors.capacitive.physics import CellResponse, TabLaw, play, play_inverse
from synth.sensors.capacitive.sensor import nominal_span_v
from tests.capacitive_scenes import tiny_capacitive_scene

QUIET = {"drift_v": 0.0, "drift_v_per_frame": 0.0}


def uniform_press(config: CapacitiveConfig, kpa: np.ndarray) -> Presses:
    """Presses whose frames carry a uniform pressure ``kpa[b, f]`` over the whole padded lattice."""
    field = np.broadcast_to(kpa[:, :, None, None], (*kpa.shape, *config.geometry.lattice_shape))
    return Presses.from_field(field.astype(np.float32), config)


def test_tab_load_operator_matches_the_boussinesq_integral() -> None:
    config = tiny_capacitive_scene().sensor
    g = config.geometry
    z = config.cover.thickness_mm
    op = tab_load_operator(g, z, quadrature=3)
    _, wp = g.lattice_shape
    h, pad, p = g.h_mm, g.pad_cells, g.pitch_mm

    def point(y: float, x: float, sy: float, sx: float) -> float:  # stress at (x, y) from a unit point load at (sx, sy)
        r2 = (x - sx) ** 2 + (y - sy) ** 2
        return 3 * z**3 / (2 * math.pi * (r2 + z * z) ** 2.5)

    for tab, (k, m) in [((1, 1), (pad + 5, pad + 5)), ((0, 2), (pad + 1, pad + 9)), ((3, 0), (2, 1))]:
        sy, sx = (k - pad + 0.5) * h, (m - pad + 0.5) * h  # the source cell's centre (mm)
        y0, x0 = tab[0] * p, tab[1] * p

        def over_source(y: float, x: float, sy: float = sy, sx: float = sx) -> float:
            return integrate.dblquad(
                lambda yy, xx: point(y, x, yy, xx), sx - h / 2, sx + h / 2, sy - h / 2, sy + h / 2
            )[0]

        exact = integrate.dblquad(over_source, x0, x0 + p, y0, y0 + p, epsabs=1e-10)[0] * 1e-3  # N per kPa
        got = op[tab[0] * g.n_cols + tab[1], k * wp + m]
        assert got == pytest.approx(exact, rel=2e-3, abs=1e-9)
    # a uniform pressure over the lattice puts p pitch^2 on an interior tab (less what lies beyond the pad)
    load = op.sum(axis=1).reshape(g.n_rows, g.n_cols)
    assert load[1, 1] == pytest.approx(p * p * 1e-3, rel=2e-3)


def test_tab_law_inverts_and_is_continuous_at_the_fill_cap() -> None:
    law = TabLaw.from_config(tiny_capacitive_scene().sensor)
    loads = np.linspace(0.0, 20.0, 4001)  # far past the tab filling its cell (fill0 z = 1 near 3.3 N)
    c = law.capacitance_pf(loads)
    assert np.all(np.diff(c) > 0)  # compressing a tab always raises its capacitance
    assert np.allclose(law.load_n(c, 1.0), loads, atol=1e-9)
    assert np.allclose(law.load_n(law.capacitance_pf(loads, 1.3), 1.3), loads, atol=1e-9)  # a stiffer tab
    assert law.capacitance_pf(np.array([-1.0]))[0] == c[0]  # a tab cannot be pulled
    cap = 1 / law.fill0 - 1  # the load (in F_s) at which the tab fills its cell
    near = law.capacitance_pf(np.array([cap * law.load_scale_n * (1 - 1e-9), cap * law.load_scale_n * (1 + 1e-9)]))
    assert abs(near[1] - near[0]) < 1e-9
    # below the unloaded capacitance the inverse continues to negative loads (an idle cell's noise)
    assert law.load_n(np.array([c[0] * 0.999]), 1.0)[0] < 0


def test_zero_load_reads_the_baseline_and_inverts_to_zero() -> None:
    config = replace(tiny_capacitive_scene().sensor, "readout.drift_v", 0.0)
    model = CapacitiveModel(config)
    stim = uniform_press(config, np.zeros((2, 3)))
    readings = model.forward(stim)
    own = model.response.static_volts(np.zeros((config.geometry.n_rows, config.geometry.n_cols)))
    assert np.allclose(readings, model.response.volts(np.zeros((1, 1, *own.shape)))[0, 0])
    assert np.allclose(model.inverse_readout(readings), 0.0, atol=1e-12)
    assert np.all(readings[0, 0] > own)  # the neighbours' crosstalk adds to every cell


def test_readings_rise_monotonically_with_load() -> None:
    config = tiny_capacitive_scene().sensor
    model = CapacitiveModel(config)
    kpa = np.linspace(0.0, 800.0, 41)[None, :]  # one press loading steadily: the loading branch
    readings = model.forward(uniform_press(config, kpa))[0]
    assert np.all(np.diff(readings, axis=0) > 0)


def test_symmetric_load_on_an_ideal_device_reads_symmetrically() -> None:
    scene = tiny_capacitive_scene(rows=4, cols=4, device={"gain_spread": 0.0, "stiffness_spread": 0.0})
    config = scene.sensor
    model = CapacitiveModel(config)
    gen = PressGenerator(config, model)
    contacts = gen.draw_contacts(1, np.random.default_rng(0))
    contacts.update(x_mm=np.array([[3.6]]), y_mm=np.array([[3.6]]), kind=np.array([[0]]), force_n=np.array([[1.5]]))
    contacts["radius_mm"] = np.array([[4.0]])
    stim = gen.press(contacts, np.ones((1, 2, 1)), np.zeros((1, 2)))
    r = model.forward(stim)[0, 0]
    assert np.allclose(r, r[::-1, :]) and np.allclose(r, r[:, ::-1]) and np.allclose(r, r.T)


def test_hysteresis_loop_closes_and_is_about_five_percent() -> None:
    config = tiny_capacitive_scene().sensor
    h = config.hysteresis
    full = config.readout.full_scale_n
    cycle = full * np.sin(np.linspace(0, np.pi, 401))[None, :]
    cycle[0, -1] = 0.0  # sin(pi) is 1e-16, not 0
    felt = play(cycle, h.play, h.play_share)[0]
    up, down = felt[:201], felt[200:][::-1]  # loading and unloading at the same applied loads
    assert np.all(up <= down + 1e-12)  # the tab lags: it feels less on the way up
    # the branches are 2 a rho of the load apart up to where the unloading branch leaves the peak
    # plateau, at F (1 + rho) = F_peak (1 - rho)
    assert np.max(down - up) / full == pytest.approx(h.width * (1 - h.play) / (1 + h.play), rel=0.02)
    assert felt[-1] == 0.0 and felt[0] == 0.0  # back to rest: the loop closes
    nominal = CellResponse.nominal(config)
    v = nominal.volts_per_pf * nominal.law.capacitance_pf(felt)
    v_up, v_down = v[:201], v[200:][::-1]
    width = np.max(v_down - v_up) / (v.max() - v[0])
    assert 0.04 <= width <= 0.06  # the seed: about 5 % of the full response


@given(st.lists(st.floats(0.0, 3.0), min_size=1, max_size=30), st.floats(0.0, 0.4), st.floats(0.05, 0.95))
def test_play_inverse_is_exact(loads: list[float], width: float, share: float) -> None:
    rho = min(width / (2 * share), 0.9)
    seq = np.array(loads)[None, :, None]
    back = play_inverse(play(seq, rho, share), rho, share)
    assert np.allclose(back, seq, atol=1e-9)


def test_effective_resolution_is_seven_bits() -> None:
    config = replace(tiny_capacitive_scene().sensor, "readout.drift_v_per_frame", 0.0)
    config = replace(config, "readout.drift_v", 0.0)
    model = CapacitiveModel(config)
    rng = np.random.default_rng(7)
    frames = uniform_press(config, np.full((400, 5), 150.0))
    clean = model.forward(frames)
    noisy = model.forward(frames, rng)
    sd = float(np.std(noisy - clean))
    enob = math.log2(nominal_span_v(config) / (sd * math.sqrt(12)))
    assert enob == pytest.approx(config.readout.effective_bits, abs=0.05)
    lsb = config.readout.lsb_v
    assert np.allclose(noisy / lsb, np.round(noisy / lsb), atol=1e-6)  # on the ADC's codes


def test_same_seed_same_bytes_and_every_output_matches_its_spec() -> None:
    scene = tiny_capacitive_scene()
    a = simulate_shard(scene, 5, 0, 20)
    b = simulate_shard(scene, 5, 0, 20)
    c = simulate_shard(scene, 6, 0, 20)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert not np.array_equal(a["readings"], c["readings"])
    specs = sensor_module("capacitive").make_simulator(scene).output_specs()
    assert set(specs) == set(a)
    for key, spec in specs.items():
        assert a[key].shape == (20, *spec.shape) and a[key].dtype == np.dtype(spec.dtype), key


def test_truth_images_carry_the_contacts_force_and_the_physics_agrees_with_float64() -> None:
    scene = tiny_capacitive_scene(stimuli={"margin_mm": 2.5}, readout=QUIET)
    config = scene.sensor
    model = CapacitiveModel(config)
    gen = PressGenerator(config, model)
    stim = gen.draw(30, np.random.default_rng(3))
    truth = gen.truth(stim, ("image", "latent", "cell_load"))
    peak = (truth["latent_force_n"][:, None, :] * truth["latent_load"]).sum(axis=2)
    # contacts well inside the array: the image holds nearly all their force
    inside = truth["force_image"].sum(axis=(2, 3))
    assert np.all(inside <= peak + 1e-6) and np.median(inside / np.maximum(peak, 1e-9)) > 0.9
    assert np.all(truth["contact_mask"].any(axis=(2, 3)) == (peak > 0))
    exact = (
        stim.field_kpa.reshape(30 * 6, -1).astype(np.float64)
        @ tab_load_operator(config.geometry, config.cover.thickness_mm).T
    )
    assert np.allclose(truth["cell_load"].reshape(exact.shape), exact, rtol=1e-5, atol=1e-7)


def test_stimulus_draws_do_not_depend_on_the_wanted_outputs() -> None:
    scene = tiny_capacitive_scene()
    full = simulate_shard(scene, 9, 0, 10)
    only = simulate_shard(scene.with_outputs(("readings",)), 9, 0, 10)
    assert np.array_equal(full["readings"], only["readings"])


def test_bad_fields_and_configs_are_refused() -> None:
    config = tiny_capacitive_scene().sensor
    shape = (1, 1, *config.geometry.lattice_shape)
    with pytest.raises(InputError, match="expected shape"):
        Presses.from_field(np.zeros((1, 3, 3)), config)
    with pytest.raises(InputError, match="negative"):
        Presses.from_field(-np.ones(shape), config)
    with pytest.raises(InputError, match="finite"):
        Presses.from_field(np.full(shape, np.nan), config)
    data = tiny_capacitive_scene().to_dict()
    data["capacitive"]["dielectric"]["tab_diameter_mm"] = 2.5
    with pytest.raises(ConfigError, match="fills its"):
        parse_scene(data)
    data = tiny_capacitive_scene().to_dict()
    data["capacitive"]["calibration"] = {"gain": [1.0] * 5, "stiffness": [1.0] * 12}
    with pytest.raises(ConfigError, match="one per cell"):
        parse_scene(data)
    data = tiny_capacitive_scene().to_dict()
    data["capacitive"]["hysteresis"] = {"width": 0.4, "play_share": 0.1}
    with pytest.raises(ConfigError, match="play"):
        parse_scene(data)
