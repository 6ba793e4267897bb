"""Property-based stress tests of the thermal fingertip: the contact solution over t in [0, 1e5] s
and beyond the parameter ranges, the simulator, the classical and shipped learned classifiers, bad
input and the recording format. Invariants, not magic numbers. `make stress` runs many more
examples (TACTILE_STRESS=1)."""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from synth.errors import DataError, InputError
from synth.materials import resolve_materials
from synth.scene import Scene, load_scene, parse_scene
from synth.sensors.thermal import (
    ContactModel,
    contact_excess,
    make_simulator,
    phi,
    spreading_conductance,
    touch_excess,
)
from tactile_learn.estimators.base import Estimator
from tactile_learn.estimators.classical.curve_match import (
    LOOKBACK,
    CurveMatchEstimator,
    detect_onset,
    drop_segments,
    nominal_sensor,
)
from tactile_learn.estimators.classical.physics_fit import PhysicsFitEstimator
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.tasks.thermal import ThermalTask
from tactile_learn.thermal_recordings import Touch, read_recordings, write_recordings
from tests.paths import REPO_ROOT

pytestmark = pytest.mark.stress

ROOT = REPO_ROOT
ONNX_MODELS = sorted(p.name for p in (ROOT / "models").glob("thermal*.onnx"))
LIBRARY = resolve_materials(())


def fewer(n: int) -> Callable[[Any], Any]:
    """At most ``n`` examples in the fast profile (a slow test); the stress profile's full count."""
    if os.environ.get("TACTILE_STRESS"):
        return settings()
    return settings(max_examples=min(n, settings.default.max_examples))


@cache
def wns() -> Scene:
    return load_scene("thermal_wns")


@cache
def full() -> Scene:
    return load_scene("thermal")


# ---- forward model: the analytic contact solution -----------------------------------------------


def log_uniform(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(math.log(lo), math.log(hi)).map(lambda v: min(max(math.exp(v), lo), hi))


#: times from 0 to 1e5 s: a fixed log grid plus a few drawn ones
T_GRID = np.concatenate([[0.0], np.geomspace(1e-9, 1e5, 160)])
times = st.lists(st.floats(0.0, 1e5), max_size=12).map(lambda ts: np.unique(np.concatenate([T_GRID, ts])))
# every documented range and beyond it: C 1..1e6, G 0 or 1e-6..1e5, H from a near-insulating to a
# near-perfect contact, e of every material and far outside them, k_s 0 or 1e-6..1e8
heat_capacity = log_uniform(1.0, 1e6)
loss = st.one_of(st.just(0.0), log_uniform(1e-6, 1e5))
conductance = st.one_of(st.sampled_from([1e-6, 1e12]), log_uniform(1e-6, 1e12))
effusivity = st.one_of(st.sampled_from([m.effusivity for m in LIBRARY]), log_uniform(1.0, 1e6))
spreading = st.one_of(st.just(0.0), log_uniform(1e-6, 1e8))
v0s = st.one_of(st.sampled_from([-100.0, 100.0]), st.floats(-100.0, 100.0))
heatings = st.one_of(st.just(0.0), st.floats(-1e4, 1e4))
dtypes = st.sampled_from([np.float32, np.float64])


def turning_points(v: np.ndarray, tol: float) -> int:
    """Sign changes of the slope, ignoring steps within ``tol`` (round-off)."""
    d = np.diff(v.astype(np.float64))
    signs = np.sign(d[np.abs(d) > tol])
    return int((np.diff(signs) != 0).sum())


def roundoff(model: ContactModel, t: np.ndarray, dtype: type) -> np.ndarray:
    """The stated round-off of ``model.excess(t, dtype)``, per time: 8 ulps of what the partial
    fractions sum, ``|V0| + sum_i |w_i phi(p_i, t)|`` (the curve's conditioning: the terms may cancel
    to a curve much smaller than they are; float32 rounds each one; measured worst case 2 ulps)."""
    r, w = model.poles
    terms = np.abs(w[..., None, :] * phi(r[..., None, :], np.asarray(t)[:, None])).sum(axis=-1)
    info = np.finfo(dtype)
    return 8 * float(info.eps) * (np.abs(model.v0) + terms) + float(info.tiny)


@given(times, heat_capacity, loss, conductance, effusivity, spreading, v0s, dtypes)
def test_curve_is_finite_starts_at_v0_and_stays_between_the_two_bodies(
    t: np.ndarray, c: float, g: float, h: float, e: float, ks: float, v0: float, dtype: type
) -> None:
    """A sensor at its steady state (S = 0) only exchanges heat with bodies at 0 (the object) and V0
    (its own steady state): the curve starts at V0 and stays between them, for every t."""
    model = ContactModel.create(c, g, h, e, ks, v0, 0.0)
    v = model.excess(t, dtype)
    assert v.dtype == dtype and v.shape == t.shape and np.isfinite(v).all()
    tol = roundoff(model, t, dtype)
    assert abs(float(v[0]) - v0) <= tol[0]
    assert (v >= min(0.0, v0) - tol).all() and (v <= max(0.0, v0) + tol).all()


@given(times, heat_capacity, loss, conductance, effusivity, spreading, v0s, heatings, dtypes)
def test_curve_has_at_most_one_turning_point(
    t: np.ndarray, c: float, g: float, h: float, e: float, ks: float, v0: float, s: float, dtype: type
) -> None:
    """The slope is a sum of decaying modes whose weights change sign at most once (Descartes' rule
    for exponential sums): at most one extremum; with no loss and no heating (pure cooling) or no
    initial difference and no loss (pure heating), none at all."""
    for g_, v0_, s_, direction in ((g, v0, s, 0.0), (0.0, v0, 0.0, -np.sign(v0)), (0.0, 0.0, s, np.sign(s))):
        model = ContactModel.create(c, g_, h, e, ks, v0_, s_)
        v = model.excess(t, dtype).astype(np.float64)
        assert np.isfinite(v).all()
        tol = 2 * float(roundoff(model, t, dtype).max())
        assert turning_points(v, tol) <= (1 if direction == 0.0 else 0)
        assert (direction * np.diff(v) >= -tol).all()  # cooling towards the object, never past it


@given(times, heat_capacity, loss, conductance, effusivity, spreading, v0s, heatings, st.floats(-10.0, 10.0))
def test_curve_is_linear_in_v0_and_heating(
    t: np.ndarray, c: float, g: float, h: float, e: float, ks: float, v0: float, s: float, a: float
) -> None:
    """The problem is linear: scaling (V0, S) scales the curve, and the curve of (V0, S) is the sum
    of those of (V0, 0) and (0, S)."""
    model = ContactModel.create(c, g, h, e, ks, v0, s)
    both = model.excess(t)
    tol = roundoff(model, t, np.float64)
    scaled = contact_excess(t, c, g, h, e, ks, a * v0, a * s)
    assert (np.abs(scaled - a * both) <= 2 * abs(a) * tol + 1e-300).all()
    parts = contact_excess(t, c, g, h, e, ks, v0, 0.0) + contact_excess(t, c, g, h, e, ks, 0.0, s)
    assert (np.abs(parts - both) <= 3 * tol).all()


@given(times, heat_capacity, loss, conductance, effusivity, spreading, v0s, heatings)
def test_float32_curve_is_within_the_stated_round_off_of_float64(
    t: np.ndarray, c: float, g: float, h: float, e: float, ks: float, v0: float, s: float
) -> None:
    model = ContactModel.create(c, g, h, e, ks, v0, s)
    a64 = model.excess(t)
    a32 = model.excess(t, np.float32)
    assert a32.dtype == np.float32 and np.isfinite(a32).all()
    assert (np.abs(a32 - a64) <= roundoff(model, t, np.float32) + roundoff(model, t, np.float64)).all()


@given(
    log_uniform(1e-8, 1e8),
    st.floats(math.pi / 2, 3 * math.pi / 2),
    st.one_of(st.sampled_from([0.0, 1e5]), st.floats(0.0, 1e5)),
    dtypes,
)
def test_phi_is_bounded_in_the_left_half_plane(r: float, angle: float, t: float, dtype: type) -> None:
    """``phi(p, t) = (erfcx(-p sqrt t) - 1) / p`` with |erfcx| <= 1 there: |phi| <= 2 / |p|, and the
    limit p -> 0 is 2 sqrt(t / pi)."""
    p = np.array([r * complex(math.cos(angle), math.sin(angle)), 0j])
    values = phi(p, np.full(2, t), dtype)
    assert np.isfinite(values).all()
    rel = 1e-5 if dtype == np.float32 else 1e-12
    assert abs(values[0]) <= 2.0 / r * (1 + rel)
    assert abs(values[1] - 2.0 * math.sqrt(t / math.pi)) <= rel * max(1.0, math.sqrt(t))


@st.composite
def records(draw: st.DrawFn) -> tuple[np.ndarray, float, float]:
    """A record's time axis (0.1 Hz .. 10 kHz), an onset on its first or last sample or anywhere
    (or before/after it), and a release: at onset, soon after, anywhere, or past the record's end."""
    fs = draw(st.sampled_from([0.1, 1.0, 50.0, 1e4]))
    n = draw(st.integers(2, 600))
    t = np.arange(n) / fs
    onset = draw(st.one_of(st.sampled_from([t[0], t[-1], -1.0 / fs, t[-1] + 1.0]), st.floats(0.0, float(t[-1]))))
    release = onset + draw(st.one_of(st.sampled_from([0.0, 1e-9, 1e9]), st.floats(0.0, float(t[-1]) + 1.0)))
    return t, onset, release


@given(records(), heat_capacity, loss, conductance, effusivity, spreading, v0s)
def test_whole_record_holds_v0_before_onset_and_recovers_after_release(
    record: tuple[np.ndarray, float, float], c: float, g: float, h: float, e: float, ks: float, v0: float
) -> None:
    t, onset, release = record
    model = ContactModel.create(c, g, h, e, ks, v0, 0.0)
    v = touch_excess(t, model, np.array(onset), np.array(release))
    assert v.shape == t.shape and np.isfinite(v).all()
    assert (v[t < onset] == v0).all()  # a sensor at its steady state: exactly V0
    tol = float(roundoff(model, np.maximum(np.minimum(t, release) - onset, 0.0), np.float64).max())
    assert (v >= min(0.0, v0) - tol).all() and (v <= max(0.0, v0) + tol).all()
    after = v[t >= max(release, onset)] - v0
    # alone again, the pixel relaxes towards its steady state V0 (G > 0) or stays put (G = 0)
    assert (np.sign(v0) * after <= tol).all() and (np.diff(np.abs(after)) <= tol).all()
    if g == 0.0:
        assert len(after) == 0 or np.ptp(after) <= tol


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [
        ("heat_capacity", 0.0, "heat_capacity: must be > 0"),
        ("heat_capacity", -1.0, "heat_capacity: must be > 0"),
        ("conductance", 0.0, "conductance: must be > 0"),
        ("effusivity", -5.0, "effusivity: must be > 0"),
        ("loss", -1e-9, "loss: must be >= 0"),
        ("spreading", -1.0, "spreading: must be >= 0"),
        ("v0", math.nan, "v0: must be finite"),
        ("heating", math.inf, "heating: must be finite"),
        ("conductance", math.inf, "conductance: must be finite"),
    ],
)
def test_contact_model_refuses_non_physical_parameters(name: str, value: float, message: str) -> None:
    params: dict[str, Any] = {
        "heat_capacity": 2000.0,
        "loss": 250.0,
        "conductance": 1e4,
        "effusivity": 500.0,
        "spreading": 10.0,
        "v0": 20.0,
        "heating": 0.0,
    }
    params[name] = np.array([params[name], value])  # one bad batch member among good ones
    with pytest.raises(InputError, match=message):
        ContactModel.create(**params)


# ---- simulator ----------------------------------------------------------------------------------


@st.composite
def thermal_scenes(draw: st.DrawFn) -> Scene:
    """Scenes over (and at the edges of) every documented range."""

    def pair(lo: float, hi: float, log: bool = False) -> list[float]:
        strategy = log_uniform(lo, hi) if log else st.floats(lo, hi)
        a, b = sorted((draw(strategy), draw(strategy)))
        return [a, b]

    data = load_scene("thermal").to_dict()
    cfg = data["thermal"]
    cfg["grid"] = [draw(st.integers(1, 3)), draw(st.integers(1, 3))]
    cfg["sensor"].update(
        heat_capacity_j_m2k=pair(1.0, 1e6, log=True),
        loss_w_m2k=pair(1e-3, 1e5, log=True),
        heater_w_m2=pair(1e-3, 1e6, log=True),
        pixel_spread=draw(st.floats(0.0, 0.3)),
        ambient_c=pair(-50.0, 100.0),
    )
    duration = draw(st.sampled_from([0.5, 6.5, 60.0]))
    fs = draw(st.sampled_from([1.0, 50.0, 400.0]))
    onset = draw(st.sampled_from([[0.0, 0.0], [0.0, duration * 0.9], [duration * 0.9, duration * 0.9]]))
    cfg["contact"].update(
        conductance_w_m2k=pair(1.0, 1e9, log=True),
        pixel_conductance_spread=draw(st.floats(0.0, 2.0)),
        radius_mm=pair(0.1, 1000.0, log=True),
        spreading=draw(st.booleans()),
        onset_s=onset,
        onset_jitter_s=draw(st.sampled_from([0.0, 0.02, 10.0])),
        contact_s=pair(1e-6, 1e5, log=True),
    )
    cfg["objects"].update(offset_k=pair(-100.0, 100.0), second_object=draw(st.floats(0.0, 1.0)))
    cfg["readout"].update(sampling_hz=fs, duration_s=duration, noise_k=draw(st.sampled_from([0.0, 0.01, 10.0])))
    cfg["window_s"] = min(cfg["window_s"], duration)
    data["noise"] = draw(st.booleans())
    return parse_scene(data)


@fewer(15)
@given(thermal_scenes(), st.integers(0, 2**32 - 1), st.sampled_from([0, 1, 5]))
def test_simulator_outputs_are_finite_and_the_baseline_is_the_steady_state(scene: Scene, seed: int, batch: int) -> None:
    out = make_simulator(scene).simulate(batch, np.random.default_rng(seed))
    cfg = scene.sensor
    for key, value in out.items():
        assert len(value) == batch, key
        if value.dtype.kind == "f":
            assert np.isfinite(value).all(), key
    readings = out["readings"]
    assert readings.shape == (batch, cfg.n_pixels, cfg.readout.n_samples) and readings.dtype == np.float32
    lo, hi = cfg.readout.adc_range_c
    if scene.noise:
        assert (readings >= lo).all() and (readings <= hi).all()
        return
    steady = (out["latent_ambient_c"] + out["latent_heater_w_m2"] / out["latent_loss_w_m2k"]).astype(np.float64)
    t = np.arange(cfg.readout.n_samples) / cfg.readout.sampling_hz
    before = t[None, None, :] < out["latent_onset_s"][..., None]
    untouched = np.broadcast_to((out["latent_material"] < 0)[..., None], readings.shape)
    expected = np.broadcast_to(steady[..., None], readings.shape)
    sel = before | untouched
    assert np.allclose(readings[sel], expected[sel], rtol=1e-6, atol=1e-4)


# ---- classifiers --------------------------------------------------------------------------------

METHODS = ["curve_match", "physics_fit", "curve_match_18", *(f"onnx:{name}" for name in ONNX_MODELS)]


@cache
def estimator(method: str) -> Estimator:
    if method.startswith("onnx:"):
        return OnnxEstimator(ROOT / "models" / method.removeprefix("onnx:")).prepare()
    if method == "curve_match_18":
        return CurveMatchEstimator(full()).prepare()
    return {"curve_match": CurveMatchEstimator, "physics_fit": PhysicsFitEstimator}[method](wns()).prepare()


def scene_of(method: str) -> Scene:
    est = estimator(method)
    return est.scene_ if isinstance(est, OnnxEstimator) else est.scene


@st.composite
def windows(draw: st.DrawFn, scene: Scene, batch: st.SearchStrategy[int]) -> np.ndarray:
    """Valid windows (inside the ADC's range): flat, contact-like (a step to an exponential or
    square-root approach), jumps, ramps, spikes, alternation and white noise, any quantisation."""
    cfg = scene.sensor
    w = cfg.window_samples
    lo, hi = cfg.readout.adc_range_c
    margin = 1e-3 * (hi - lo)
    t = np.arange(w, dtype=np.float64)
    rows = []
    for _ in range(draw(batch)):
        kind = draw(st.sampled_from(["flat", "exp", "sqrt", "jump", "ramp", "spike", "alternate", "noise"]))
        b = draw(st.floats(lo + margin, hi - margin))
        k = draw(st.integers(0, w - 1))
        target = draw(st.floats(lo + margin, hi - margin))
        if kind == "flat":
            x = np.full(w, b)
        elif kind == "exp":
            tau = draw(log_uniform(0.01, 1e4))
            x = b + (target - b) * -np.expm1(-np.maximum(t - k, 0.0) / tau)
        elif kind == "sqrt":
            x = b + (target - b) * np.sqrt(np.maximum(t - k, 0.0) / w)
        elif kind == "jump":
            x = np.where(t < k, b, target)
        elif kind == "ramp":
            x = np.linspace(b, target, w)
        elif kind == "spike":
            x = np.where(t == k, target, b)
        elif kind == "alternate":
            x = np.where(t % 2 == 0, b, target)
        else:
            rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
            x = b + draw(log_uniform(1e-6, 10.0)) * rng.standard_normal(w)
        step = draw(st.sampled_from([0.0, 1e-4, cfg.readout.adc_step_k, 0.5]))
        if step:
            x = np.round(x / step) * step
        rows.append(np.clip(x, lo + margin, hi - margin))
    return np.array(rows, dtype=np.float64).reshape(-1, w)


def check_probabilities(p: np.ndarray, n: int, scene: Scene) -> None:
    k = len(scene.sensor.material_list) + 1
    assert p.shape == (n, k) and p.dtype == np.float32
    assert np.isfinite(p).all() and (p >= 0).all()
    assert np.allclose(p.sum(axis=1), 1.0, atol=1e-5)


@pytest.mark.parametrize("method", METHODS)
@fewer(15)
@given(data=st.data())
def test_any_valid_window_gives_probabilities(method: str, data: st.DataObject) -> None:
    scene = scene_of(method)
    x = data.draw(windows(scene, st.sampled_from([0, 1, 2, 4])))
    check_probabilities(estimator(method).predict_proba(x), len(x), scene)


@pytest.mark.parametrize("method", METHODS)
@fewer(10)
@given(data=st.data())
def test_dtype_layout_and_read_only_inputs_give_the_same_answer(method: str, data: st.DataObject) -> None:
    scene = scene_of(method)
    x = data.draw(windows(scene, st.integers(1, 3)))
    est = estimator(method)
    ref = est.predict_proba(x.astype(np.float32))
    frozen = x.astype(np.float32)
    frozen.setflags(write=False)
    variants = {
        "float64": x,
        "big-endian": x.astype(">f8"),
        "fortran": np.asfortranarray(x.astype(np.float32)),
        "strided": np.repeat(x.astype(np.float32), 2, axis=1)[:, ::2],
        "reversed rows": x[::-1][::-1],
        "read-only": frozen,
        "list": x.astype(np.float32).tolist(),
    }
    for name, variant in variants.items():
        assert np.array_equal(est.predict_proba(variant), ref), name
    assert not frozen.flags.writeable


@cache
def simulated_windows(name: str, n: int) -> np.ndarray:
    scene = load_scene(name)
    arrays = make_simulator(scene).simulate(n, np.random.default_rng(11))
    return ThermalTask().example_inputs(arrays, scene)


@pytest.mark.parametrize("method", METHODS)
def test_large_batches_and_chunks_answer_row_by_row(method: str) -> None:
    """Rows are independent: a large batch (several chunks), its reversal and single rows agree."""
    scene = scene_of(method)
    x = simulated_windows(scene.name, 12)  # 12 touches x 16 pixels
    est = estimator(method)
    p = est.predict_proba(x)
    check_probabilities(p, len(x), scene)
    tol = 1e-6 if method.startswith("onnx:") else 0.0
    assert np.allclose(est.predict_proba(x[::-1])[::-1], p, rtol=0, atol=tol)
    for i in (0, len(x) // 2, len(x) - 1):
        assert np.allclose(est.predict_proba(x[i : i + 1])[0], p[i], rtol=0, atol=tol)
    if method == "physics_fit":
        chunked = PhysicsFitEstimator(scene, chunk=37).prepare().predict_proba(x)
        assert np.array_equal(chunked, p)


@pytest.mark.parametrize("method", ["curve_match", "physics_fit", "curve_match_18"])
@fewer(15)
@given(level=st.floats(0.0, 1.0), step=st.sampled_from([0.0, 1e-4, 0.01, 0.5]), batch=st.integers(1, 3))
def test_flat_windows_are_none(method: str, level: float, step: float, batch: int) -> None:
    """A flat window (no contact, or a sensor that never moved) is 'none' with certainty."""
    scene = scene_of(method)
    lo, hi = scene.sensor.readout.adc_range_c
    value = lo + (hi - lo) * (1e-3 + 0.998 * level)
    if step:
        value = min(max(round(value / step) * step, lo + step), hi - step)
    x = np.full((batch, scene.sensor.window_samples), value)
    p = estimator(method).predict_proba(x)
    check_probabilities(p, batch, scene)
    assert (p[:, -1] == 1.0).all()


@st.composite
def noise_free_touches(draw: st.DrawFn, scene: Scene) -> tuple[np.ndarray, int, int]:
    """A noise-free window of the scene's nominal sensor touching a material at its nominal
    properties (conductance, radius, object temperature and onset anywhere in the scene's ranges,
    at least 3 baseline and 3 contact samples); returns it, the last baseline sample and the
    material."""
    cfg = scene.sensor
    w, fs = cfg.window_samples, cfg.readout.sampling_hz
    c, g = nominal_sensor(cfg)
    mat = draw(st.integers(0, len(cfg.material_list) - 1))
    m = cfg.material_list[mat]
    h = draw(log_uniform(*cfg.contact.conductance_w_m2k))
    radius = draw(st.floats(*cfg.contact.radius_mm)) * 1e-3
    ks = float(spreading_conductance(m.k_w_mk, radius)) if cfg.contact.spreading else 0.0
    heater = draw(st.floats(*cfg.sensor.heater_w_m2))
    offset = draw(st.floats(*cfg.objects.offset_k))
    ambient = draw(st.floats(*cfg.sensor.ambient_c))
    k0 = draw(st.integers(2, w - 4))
    onset = (k0 + draw(st.floats(0.0, 1.0, exclude_max=True))) / fs
    model = ContactModel.create(c, g, h, m.effusivity, ks, heater / g - offset, 0.0)
    x = ambient + offset + touch_excess(np.arange(w) / fs, model, np.array(onset), np.array(1e9))
    return x[None, :], k0, mat


@pytest.mark.parametrize("name", ["thermal_wns", "thermal"])
@given(data=st.data(), quantise=st.booleans())
def test_noise_free_onset_is_found_on_its_sample_with_the_noise_floor(
    name: str, data: st.DataObject, quantise: bool
) -> None:
    """A clean (or sub-LSB-noise) sensor's flat baseline is the baseline, not padding: the onset is
    the last baseline sample (one later at most, when the first contact sample departs by less than
    the noise floor or quantisation hides it) and the noise estimate is the floor (none was seen)."""
    scene = load_scene(name)
    x, k0, _ = data.draw(noise_free_touches(scene))
    step = scene.sensor.readout.adc_step_k
    if quantise:
        x = np.round(x / step) * step
    onset = detect_onset(x, scene.sensor.readout.sampling_hz, step)
    assert onset.detected[0]
    assert k0 <= onset.index[0] <= k0 + 1
    assert onset.sigma[0] == max(step / math.sqrt(12.0), 1e-3)
    assert abs(onset.baseline[0] - x[0, 0]) <= 1e-9


@pytest.mark.parametrize("method", ["curve_match", "curve_match_18"])
@given(data=st.data())
def test_a_library_template_is_classified_as_its_material(method: str, data: st.DataObject) -> None:
    """Consistency with the forward model: a noise-free curve that is exactly one of the library's
    templates (any conductance, radius, onset phase up to a sample, amplitude and temperature) is
    aligned on its onset, its own material fits it to round-off, and the prediction is a material
    that does (the only one, unless the contact is a few samples short and others fit it as well)."""
    est = estimator(method)
    assert isinstance(est, CurveMatchEstimator)
    lib = est.library_
    w = est.scene.sensor.window_samples
    lo, hi = est.scene.sensor.readout.adc_range_c
    pick = data.draw(st.sampled_from(np.flatnonzero(lib.phase <= 1.0).tolist()))
    k0 = data.draw(st.integers(2, w - 3))
    v0 = data.draw(st.floats(*nominal_v0(est.scene)))
    base = data.draw(st.floats(lo + v0 + 1.0, hi - 1.0))
    j = np.arange(w) - k0
    f = np.where(j >= -LOOKBACK, lib.templates[pick][np.clip(j + LOOKBACK, 0, None)], 0.0)
    x = (base - v0 * f)[None, :]
    _, onset, _ = est.scores(x)
    assert onset.index[0] == k0
    y, n_valid = drop_segments(x, onset, lib.lookback)
    rss, _ = lib.match(y, n_valid)
    best = rss[0] <= rss[0].min() + 1e-9 * float((y * y).sum())  # RSS = |y|^2 - gain: round-off of |y|^2
    assert best[lib.material[pick]]
    assert best[int(np.argmax(est.predict_proba(x)[0]))]


def nominal_v0(scene: Scene) -> tuple[float, float]:
    """The range of V0 = Q/G - offset the scene allows."""
    s, o = scene.sensor.sensor, scene.sensor.objects
    return s.heater_w_m2[0] / s.loss_w_m2k[1] - o.offset_k[1], s.heater_w_m2[1] / s.loss_w_m2k[0] - o.offset_k[0]


# ---- bad input ----------------------------------------------------------------------------------

BAD_INPUTS: list[tuple[str, Callable[[int], Any], str]] = [
    ("nan", lambda w: np.full((2, w), np.nan), "NaN or inf"),
    ("inf", lambda w: np.full((1, w), np.inf), "NaN or inf"),
    ("-inf", lambda w: np.full((1, w), -np.inf), "NaN or inf"),
    ("negative", lambda w: np.full((1, w), -5.0), "negative"),
    ("at the ADC's top", lambda w: np.full((1, w), 100.0), "saturated"),
    ("above the ADC's top", lambda w: np.full((1, w), 1e30), "saturated"),
    ("at the ADC's bottom", lambda w: np.zeros((1, w)), "saturated"),
    ("too long", lambda w: np.full((1, w + 1), 30.0), r"expected shape \('B', \d+\)"),
    ("too short", lambda w: np.full((3, w - 1), 30.0), r"expected shape"),
    ("no batch axis", lambda w: np.full(w, 30.0), "batch axis"),
    ("3-d", lambda w: np.full((1, 1, w), 30.0), "expected shape"),
    ("scalar", lambda w: 30.0, "expected shape"),
    ("strings", lambda w: np.array([["30"] * w]), "expected numbers"),
    ("objects", lambda w: np.array([[None] * w], dtype=object), "expected numbers"),
    ("complex", lambda w: np.full((1, w), 30 + 1j), "real numbers"),
    ("ragged", lambda w: [[30.0] * w, [30.0] * (w - 1)], "cannot be read|expected numbers"),
]


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize(("case", "make", "message"), BAD_INPUTS, ids=[b[0] for b in BAD_INPUTS])
def test_bad_input_is_refused_with_a_message_naming_it(
    method: str, case: str, make: Callable[[int], Any], message: str
) -> None:
    scene = scene_of(method)
    with pytest.raises(InputError, match=message):
        estimator(method).predict_proba(make(scene.sensor.window_samples))


@pytest.mark.parametrize("method", METHODS)
@fewer(15)
@given(data=st.data(), bad=st.sampled_from([math.nan, math.inf, -math.inf, -1e-3, 0.0, 100.0, 1e9]))
def test_one_bad_value_in_a_valid_batch_names_its_frame(method: str, data: st.DataObject, bad: float) -> None:
    scene = scene_of(method)
    x = data.draw(windows(scene, st.integers(1, 4)))
    row = data.draw(st.integers(0, len(x) - 1))
    col = data.draw(st.integers(0, x.shape[1] - 1))
    x[row, col] = bad
    with pytest.raises(InputError, match=rf"(frame {row})|(NaN or inf.*frame {row})"):
        estimator(method).predict_proba(x)


# ---- recordings and evaluation files --------------------------------------------------------------


@st.composite
def touches(draw: st.DrawFn) -> list[Touch]:
    names = [m.name for m in wns().sensor.material_list]
    out = []
    for i in range(draw(st.integers(1, 3))):
        n = draw(st.integers(2, 60))
        t0 = draw(st.sampled_from([0.0, -5.0, 1.7e9]))
        dt = draw(st.one_of(st.sampled_from([1e-7, 1e-4, 0.02, 10.0]), log_uniform(1e-7, 10.0)))
        time = t0 + dt * np.cumsum(draw(st.lists(st.floats(1.0, 3.0), min_size=n, max_size=n)))
        assume(np.all(np.diff(time) > 0))  # representable as distinct floats
        temp = np.array(draw(st.lists(st.floats(-50.0, 150.0), min_size=n, max_size=n)))
        onset = draw(st.one_of(st.none(), st.floats(float(time[0]), float(time[-1]))))
        material = draw(st.sampled_from([None, *names]))
        info = {"operator": draw(st.sampled_from(["", "ann", "b,c"]))}
        out.append(Touch(f"touch-{i:03d}.csv", time, temp, material, onset, info))
    return out


@fewer(15)
@given(touches())
def test_recordings_round_trip_without_losing_samples(tmp_path_factory: pytest.TempPathFactory, data: list) -> None:
    """What write_recordings writes reads back: every sample (time to the float, temperature to the
    format's 1e-5 K), labels, onsets and extra columns."""
    folder = tmp_path_factory.mktemp("rec")
    write_recordings(folder, data)
    back = read_recordings(folder, [m.name for m in wns().sensor.material_list])
    assert len(back) == len(data)
    for a, b in zip(data, back, strict=True):
        assert np.array_equal(a.time_s, b.time_s)
        assert np.allclose(a.temperature_c, b.temperature_c, rtol=0, atol=1e-5)
        assert a.material == b.material and a.info == b.info
        assert (a.onset_s is None) == (b.onset_s is None)
        if a.onset_s is not None:
            assert b.onset_s == pytest.approx(a.onset_s, abs=1e-6)


GOOD_TOUCH = "time_s,temperature_c\n0,40\n0.02,40\n0.04,39.5\n0.06,39.2\n"
#: (corruption, touches.csv, {file: text or bytes}, message)
CORRUPT: list[tuple[str, str | bytes, dict[str, str | bytes], str]] = [
    ("empty index", "", {}, "touches.csv: empty file"),
    ("blank index", "\n\n", {}, "touches.csv: empty file"),
    ("index header only", "file,material\n", {}, "lists no touches"),
    ("index lacks material", "file\na.csv\n", {"a.csv": GOOD_TOUCH}, "missing column.*material"),
    ("index lacks file", "material\noak\n", {}, "missing column.*file"),
    (
        "index row too long",
        "file,material\na.csv,oak,extra\n",
        {"a.csv": GOOD_TOUCH},
        "row 2: 3 fields, the header has 2",
    ),
    ("index empty file name", "file,material\n,oak\n", {}, "row 2: empty file name"),
    ("index not utf-8", b"\xff\xfe\x00\x01file", {}, "touches.csv: cannot be read"),
    ("unknown material", "file,material\na.csv,kryptonite\n", {"a.csv": GOOD_TOUCH}, "unknown material 'kryptonite'"),
    ("material not in scene", "file,material\na.csv,copper\n", {"a.csv": GOOD_TOUCH}, "not in the scene's list"),
    ("onset not a number", "file,material,onset_s\na.csv,oak,soon\n", {"a.csv": GOOD_TOUCH}, "onset_s: 'soon'"),
    ("onset nan", "file,material,onset_s\na.csv,oak,nan\n", {"a.csv": GOOD_TOUCH}, "onset_s: 'nan' is not a finite"),
    ("touch missing", "file,material\na.csv,oak\n", {}, "a.csv: touch file not found"),
    ("touch empty", "file,material\na.csv,oak\n", {"a.csv": ""}, "a.csv: empty file"),
    ("touch header only", "file,material\na.csv,oak\n", {"a.csv": "time_s,temperature_c\n"}, "at least 2 samples"),
    ("touch one sample", "file,material\na.csv,oak\n", {"a.csv": "time_s,temperature_c\n0,30\n"}, "has 1"),
    (
        "touch lacks temperature",
        "file,material\na.csv,oak\n",
        {"a.csv": "time_s,temp\n0,1\n1,2\n"},
        "missing column.*temperature_c",
    ),
    ("touch row too short", "file,material\na.csv,oak\n", {"a.csv": "time_s,temperature_c\n0,30\n1\n"}, "row 3"),
    (
        "time goes back",
        "file,material\na.csv,oak\n",
        {"a.csv": "time_s,temperature_c\n0,30\n0.2,30\n0.1,29\n"},
        "row 4: time_s does not increase",
    ),
    (
        "time repeats",
        "file,material\na.csv,oak\n",
        {"a.csv": "time_s,temperature_c\n0,30\n0,30\n0.1,29\n"},
        "row 3: time_s does not increase",
    ),
    ("nan reading", "file,material\na.csv,oak\n", {"a.csv": "time_s,temperature_c\n0,30\n1,nan\n"}, "not a finite"),
    ("inf time", "file,material\na.csv,oak\n", {"a.csv": "time_s,temperature_c\n0,30\ninf,30\n"}, "not a finite"),
    ("text reading", "file,material\na.csv,oak\n", {"a.csv": "time_s,temperature_c\n0,30\n1,warm\n"}, "not a number"),
    ("touch not utf-8", "file,material\na.csv,oak\n", {"a.csv": b"\xff\xfe\x00\x01"}, "a.csv: cannot be read"),
    (
        "time in microseconds",
        "file,material\na.csv,oak\n",
        {"a.csv": "time_s,temperature_c\n0,30\n20000,30\n1e9,29\n"},
        "is time_s in seconds",
    ),
    (
        "time beyond float",
        "file,material\na.csv,oak\n",
        {"a.csv": "time_s,temperature_c\n-1e308,30\n1e308,29\n"},
        "is time_s in seconds",
    ),
]


@pytest.mark.parametrize(("case", "index", "files", "message"), CORRUPT, ids=[c[0] for c in CORRUPT])
def test_corrupt_recordings_give_a_data_error_naming_the_problem(
    tmp_path: Path, case: str, index: str | bytes, files: dict[str, str | bytes], message: str
) -> None:
    (tmp_path / "touches.csv").write_bytes(index if isinstance(index, bytes) else index.encode())
    for name, text in files.items():
        (tmp_path / name).write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(DataError, match=message):
        ThermalTask().load_eval_data(tmp_path, wns())


@pytest.mark.parametrize("span", ["0.001", "0.03", "1e-9"])
def test_calibration_refuses_records_too_short_to_hold_a_contact(tmp_path: Path, span: str) -> None:
    """A record shorter than one sample period at the scene's rate resamples to a single sample: a
    typed error, not a crash in the onset detection."""
    (tmp_path / "touches.csv").write_text("file,material\na.csv,oak\n")
    (tmp_path / "a.csv").write_text(f"time_s,temperature_c\n0,30\n{span},29\n")
    with pytest.raises(DataError, match=r"a\.csv: (too few samples of contact|no contact found)"):
        ThermalTask().calibrate(tmp_path, tmp_path / "out.toml", wns())
    onset = detect_onset(np.array([[30.0]]), 50.0, 0.01)  # a one-sample window: defined, no contact
    assert not onset.detected.any() and np.isfinite(onset.sigma).all()


NPZ_R = 200
#: (case, arrays, message) for evaluation .npz files
BAD_NPZ: list[tuple[str, dict[str, Any], str]] = [
    ("no readings", {"latent_material": np.zeros(2, int)}, "needs an array 'readings'"),
    ("no labels", {"readings": np.full((2, NPZ_R), 30.0)}, "needs labels"),
    ("string readings", {"readings": np.full((2, NPZ_R), "30"), "latent_material": np.zeros(2, int)}, "real numbers"),
    ("one sample", {"readings": np.full((2, 1), 30.0), "latent_material": np.zeros(2, int)}, "expected \\(B, R\\)"),
    ("labels too short", {"readings": np.full((3, NPZ_R), 30.0), "latent_material": np.zeros(2, int)}, "labels have"),
    ("fractional labels", {"readings": np.full((2, NPZ_R), 30.0), "latent_material": np.array([0.5, 1])}, "integer"),
    ("nan labels", {"readings": np.full((2, NPZ_R), 30.0), "latent_material": np.array([np.nan, 1])}, "integer"),
    ("label out of range", {"readings": np.full((2, NPZ_R), 30.0), "latent_material": np.array([0, 7])}, r"\[-1, 2\]"),
    ("unknown name", {"readings": np.full((1, NPZ_R), 30.0), "material": np.array(["gold"])}, "gold"),
    (
        "nan onset",
        {"readings": np.full((2, NPZ_R), 30.0), "latent_material": np.zeros(2, int), "onset_s": [np.nan, 1.0]},
        "onset_s must be finite",
    ),
    (
        "onset too long",
        {"readings": np.full((2, NPZ_R), 30.0), "latent_material": np.zeros(2, int), "onset_s": [1.0, 1.0, 1.0]},
        "onset_s have shape",
    ),
]


@pytest.mark.parametrize(("case", "arrays", "message"), BAD_NPZ, ids=[b[0] for b in BAD_NPZ])
def test_bad_evaluation_files_give_a_data_error_naming_the_problem(
    tmp_path: Path, case: str, arrays: dict[str, Any], message: str
) -> None:
    path = tmp_path / "eval.npz"
    np.savez(path, **arrays)
    with pytest.raises(DataError, match=message):
        ThermalTask().load_eval_data(path, wns())


@fewer(10)
@given(
    batch=st.sampled_from([0, 1, 3]),
    onset=st.one_of(st.sampled_from([-1e30, -1.0, 0.0, 1e30]), st.floats(-10.0, 10.0)),
)
def test_far_off_or_empty_evaluation_files_load_and_evaluate(
    tmp_path_factory: pytest.TempPathFactory, batch: int, onset: float
) -> None:
    """Onsets before the record, after it or absurdly far off, and empty files: defined views (no
    integer overflow), metrics without a crash."""
    path = tmp_path_factory.mktemp("npz") / "eval.npz"
    rng = np.random.default_rng(batch)
    np.savez(
        path,
        readings=30 + 0.01 * rng.standard_normal((batch, NPZ_R)),
        latent_material=np.zeros(batch, dtype=int),
        onset_s=np.full(batch, onset),
    )
    task = ThermalTask()
    data = task.load_eval_data(path, wns())
    assert data.inputs.shape == (batch, wns().sensor.window_samples)
    metrics = task.evaluate(estimator("curve_match"), data)
    assert "accuracy" in metrics
