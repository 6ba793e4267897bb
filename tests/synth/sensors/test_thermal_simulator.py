"""The thermal fingertip simulator: material library, scenes, outputs, latents, layout, noise."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from synth.config import replace
from synth.dataset import simulate_shard
from synth.errors import ConfigError, InputError
from synth.materials import FAMILIES, effusivity_range, get_material, library, sample_properties
from synth.scene import load_scene, parse_scene
from synth.sensors.thermal import ContactModel, ThermalConfig, make_simulator, touch_excess
from synth.sensors.thermal.stimuli import Touches

#: effusivities of the reference table (physics.md section 3), W s^0.5 / (m^2 K)
REFERENCE_E = {
    "copper": 37100,
    "aluminium": 24000,
    "brass": 18900,
    "mild_steel": 13600,
    "stainless_steel": 8050,
    "marble": 2700,
    "granite": 2500,
    "glass": 1430,
    "nylon66": 682,
    "polypropylene": 602,
    "pmma": 595,
    "pvc": 449,
    "rubber": 469,
    "oak": 380,
    "pine": 291,
    "plywood": 282,
    "foam": 38,
}


def test_library_has_the_reference_materials_and_families() -> None:
    mats = library()
    assert len(mats) >= 15 and {m.family for m in mats} == set(FAMILIES)
    for name, e in REFERENCE_E.items():
        assert get_material(name).effusivity == pytest.approx(e, rel=0.03)
    assert get_material("Mild Steel").name == "mild_steel"
    with pytest.raises(ConfigError, match="unknown material"):
        get_material("unobtainium")
    # the reference's overlapping pairs do overlap within their spreads
    for a, b in (("pine", "plywood"), ("pmma", "polypropylene"), ("pvc", "rubber"), ("marble", "granite")):
        (lo_a, hi_a), (lo_b, hi_b) = effusivity_range(get_material(a)), effusivity_range(get_material(b))
        assert lo_a < hi_b and lo_b < hi_a


def test_sampled_properties_stay_within_their_spread(rng: np.random.Generator) -> None:
    mats = library()
    idx = rng.integers(0, len(mats), size=5000)
    props = sample_properties(mats, idx, rng)
    lo = np.array([effusivity_range(m)[0] for m in mats])[idx]
    hi = np.array([effusivity_range(m)[1] for m in mats])[idx]
    assert ((props.effusivity >= lo * (1 - 1e-12)) & (props.effusivity <= hi * (1 + 1e-12))).all()


def test_scenes_load_and_validate() -> None:
    full, wns = load_scene("thermal"), load_scene("thermal_wns")
    assert isinstance(full.sensor, ThermalConfig) and len(full.sensor.material_list) == len(library())
    assert [m.name for m in wns.sensor.material_list] == ["oak", "nylon66", "mild_steel"]
    data = full.to_dict()
    data["thermal"]["objects"]["materials"] = ["oak", "kryptonite"]
    with pytest.raises(ConfigError, match="kryptonite"):
        parse_scene(data, "bad")
    data = full.to_dict()
    data["thermal"]["window_s"] = 100.0
    with pytest.raises(ConfigError, match="window_s"):
        parse_scene(data, "bad")
    data = full.to_dict()
    data["thermal"]["contact"]["conductance_w_m2k"] = [5000.0, 100.0]
    with pytest.raises(ConfigError, match="conductance_w_m2k"):
        parse_scene(data, "bad")


def test_outputs_specs_determinism_and_subsets(rng: np.random.Generator) -> None:
    scene = load_scene("thermal")
    sim = make_simulator(scene)
    out = sim.simulate(6, np.random.default_rng(1))
    specs = sim.output_specs()
    assert set(out) == set(specs)
    for key, spec in specs.items():
        assert out[key].shape == (6, *spec.shape) and out[key].dtype == np.dtype(spec.dtype), key
    again = sim.simulate(6, np.random.default_rng(1))
    assert all(np.array_equal(out[k], again[k]) for k in out)
    only = make_simulator(scene.with_outputs(("readings",))).simulate(6, np.random.default_rng(1))
    assert set(only) == {"readings"} and np.array_equal(only["readings"], out["readings"])
    latent = make_simulator(scene.with_outputs(("latent",))).simulate(6, np.random.default_rng(1))
    assert "readings" not in latent and np.array_equal(latent["latent_material"], out["latent_material"])


def test_latents_are_consistent_and_noise_off_is_the_physics() -> None:
    scene = load_scene("thermal").with_noise(False)
    cfg: ThermalConfig = scene.sensor
    arrays = simulate_shard(scene, 5, 0, 40)
    touched = arrays["latent_material"] >= 0
    assert touched.any(axis=1).all() and (~touched).any()  # every touch has contact, some pixels none
    fam = np.array([m.family_index for m in cfg.material_list])
    assert np.array_equal(arrays["latent_family"][touched], fam[arrays["latent_material"][touched]])
    e = np.sqrt(arrays["latent_k_w_mk"] * arrays["latent_rho_kg_m3"] * arrays["latent_c_j_kgk"])
    assert np.allclose(e[touched], arrays["latent_effusivity"][touched], rtol=1e-5)
    v0 = (
        arrays["latent_ambient_c"]
        + arrays["latent_heater_w_m2"] / arrays["latent_loss_w_m2k"]
        - arrays["latent_object_c"]
    )
    assert np.allclose(v0[touched], arrays["latent_v0_k"][touched], atol=1e-3)
    readings = arrays["readings"].astype(np.float64)
    # pixels touching nothing sit at their steady state the whole record
    assert np.ptp(readings[~touched], axis=1).max() < 1e-3
    # a touched pixel's clean curve is the physics model with its own latents
    t = np.arange(readings.shape[-1]) / cfg.readout.sampling_hz
    rows = np.argwhere(touched)[:10]
    for b, p in rows:
        lat = {k: float(v[b, p]) for k, v in arrays.items() if k.startswith("latent_")}
        model = ContactModel.create(
            lat["latent_heat_capacity_j_m2k"],
            lat["latent_loss_w_m2k"],
            lat["latent_conductance_w_m2k"],
            lat["latent_effusivity"],
            lat["latent_spreading_w_m2k"],
            lat["latent_v0_k"],
        )
        expect = lat["latent_object_c"] + touch_excess(
            t, model, np.array(lat["latent_onset_s"]), np.array(lat["latent_release_s"])
        )
        assert np.allclose(readings[b, p], expect, atol=2e-3)
        # cools on contact (object colder than the pixel), recovers after release
        on = math.ceil(lat["latent_onset_s"] * cfg.readout.sampling_hz)
        off = math.ceil(lat["latent_release_s"] * cfg.readout.sampling_hz)
        assert readings[b, p, off - 1] < readings[b, p, on - 1]
        if off + 5 < readings.shape[-1]:
            assert readings[b, p, -1] > readings[b, p, off]


def test_noise_and_adc_switch_with_the_scene() -> None:
    scene = load_scene("thermal_wns")
    noisy = simulate_shard(scene, 9, 0, 8)["readings"]
    clean = simulate_shard(scene.with_noise(False), 9, 0, 8)["readings"]
    step = scene.sensor.readout.adc_step_k
    assert np.allclose(noisy / step, np.round(noisy / step), atol=1e-3)
    resid = (noisy - clean).astype(np.float64)
    assert 0.5 * scene.sensor.readout.noise_k < resid.std() < 2.0 * scene.sensor.readout.noise_k
    assert np.isfinite(clean).all() and np.isfinite(noisy).all()


def test_single_pixel_grid_and_the_seeds_two_objects(rng: np.random.Generator) -> None:
    scene = load_scene("thermal_wns")
    one = make_simulator(dataclasses.replace(scene, sensor=replace(scene.sensor, "grid", [1, 1])))
    out = one.simulate(20, rng)
    assert out["readings"].shape[1] == 1 and (out["latent_material"] >= 0).all()
    two = make_simulator(dataclasses.replace(scene, sensor=replace(scene.sensor, "objects.second_object", 1.0)))
    layout = two.simulate(50, rng)["latent_object"]
    assert ((layout == 0).any(axis=1) & (layout == 1).any(axis=1)).all()


@pytest.mark.parametrize(("field", "value"), [("object_c", -300.0), ("ambient_c", -273.15)])
def test_a_temperature_at_or_below_absolute_zero_is_refused(field: str, value: float) -> None:
    config = load_scene("thermal").sensor
    kwargs = {"object_c": 20.0, "ambient_c": 22.0, field: value}
    common = {"k_w_mk": 0.2, "rho_kg_m3": 600.0, "c_j_kgk": 1700.0, "conductance_w_m2k": 1e4}
    with pytest.raises(InputError, match=f"{field}: .* absolute zero"):
        Touches.from_objects(config, **kwargs, **common, radius_mm=5.0, onset_s=2.6, contact_s=2.5)
    kwargs[field] = -273.0  # just above it: a valid (if cold) temperature
    assert len(Touches.from_objects(config, **kwargs, **common, radius_mm=5.0, onset_s=2.6, contact_s=2.5)) == 1
