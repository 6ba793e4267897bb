"""Thermal fingertip physics: the analytic contact solution against independent solutions, its
numerical stability over t in [0, 1e5] s in float32 and float64, recovery, and the readout."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy import special

from synth.config import from_dict
from synth.materials import get_material
from synth.sensors.thermal import (
    ContactModel,
    Readout,
    ReadoutConfig,
    contact_excess,
    phi,
    recovery_excess,
    spreading_conductance,
    touch_excess,
)
from tests.thermal_reference import numerical_excess

T_CHECK = np.geomspace(0.01, 20.0, 80)
T_LONG = np.concatenate([[0.0], np.geomspace(1e-6, 1e5, 300)])
C, G = 2000.0, 250.0


def seed_eq5(t: np.ndarray, mc: float, q: float, k: float, alpha: float, v0: float) -> np.ndarray:
    """The seed's eq. 5 at x = 0 (perfect contact, no loss), written with erfcx."""
    h = k / (mc * alpha)
    z = h * np.sqrt(alpha * t)
    return q / (k * h) * (2 * z / math.sqrt(math.pi) - 1 + special.erfcx(z)) + v0 * special.erfcx(z)


@pytest.mark.parametrize("material", ["mild_steel", "nylon66", "oak"])
@pytest.mark.parametrize(
    ("loss", "conductance", "radius_mm", "heating"),
    [(G, 1e4, None, 0.0), (0.0, 5e3, None, 0.0), (G, 3e3, 5.0, 0.0), (0.0, 2e4, None, 300.0), (G, 8e3, 3.0, 100.0)],
)
def test_analytic_matches_numerical_solution(
    material: str, loss: float, conductance: float, radius_mm: float | None, heating: float
) -> None:
    m = get_material(material)
    ks = 0.0 if radius_mm is None else float(spreading_conductance(m.k_w_mk, radius_mm * 1e-3))
    analytic = contact_excess(T_CHECK, C, loss, conductance, m.effusivity, ks, 10.0, heating)
    numeric = numerical_excess(T_CHECK, C, loss, conductance, m.k_w_mk, m.diffusivity_mm2_s * 1e-6, ks, 10.0, heating)
    assert np.max(np.abs(analytic - numeric) / np.abs(numeric)) <= 0.01
    # stricter: the change from V0 (what classifiers use) agrees to 1 % of its largest value too
    assert np.max(np.abs(analytic - numeric)) <= 0.01 * np.max(np.abs(numeric - 10.0))


def test_double_root_is_continuous_and_correct() -> None:
    """C H = 4 e^2 (G = k_s = 0) makes the two roots coincide: the nudge keeps the curve right."""
    m = get_material("glass")
    h_double = 4 * m.effusivity**2 / C
    curves = [
        contact_excess(T_CHECK, C, 0.0, h, m.effusivity, 0.0, 10.0) for h in h_double * np.array([0.999, 1.0, 1.001])
    ]
    assert np.max(np.abs(curves[1] - curves[0])) < 1e-3 and np.max(np.abs(curves[1] - curves[2])) < 1e-3
    numeric = numerical_excess(T_CHECK, C, 0.0, h_double, m.k_w_mk, m.diffusivity_mm2_s * 1e-6, 0.0, 10.0)
    assert np.max(np.abs(curves[1] - numeric) / numeric) <= 0.01


@pytest.mark.parametrize("material", ["copper", "stainless_steel", "pmma", "pine", "foam"])
def test_perfect_contact_is_the_seeds_eq5(material: str) -> None:
    m = get_material(material)
    alpha = m.diffusivity_mm2_s * 1e-6
    ours = contact_excess(T_CHECK, 1500.0, 0.0, 1e11, m.effusivity, 0.0, 8.0, 400.0)
    seed = seed_eq5(T_CHECK, 1500.0, 400.0, m.k_w_mk, alpha, 8.0)
    assert np.allclose(ours, seed, rtol=1e-4, atol=1e-6)


def test_naive_formula_overflows_where_ours_does_not() -> None:
    m = get_material("copper")
    h = m.k_w_mk / (C * m.diffusivity_mm2_s * 1e-6)
    t = np.array([1e3, 1e5], dtype=np.float32)
    z = (h * np.sqrt(m.diffusivity_mm2_s * 1e-6 * t)).astype(np.float32)
    with np.errstate(over="ignore", invalid="ignore"):
        naive = np.exp(z * z) * special.erfc(z)
    assert not np.isfinite(naive).all()  # inf * 0 past z ~ 9.4 in float32
    for dtype in (np.float32, np.float64):
        v = contact_excess(t, C, 0.0, 1e9, m.effusivity, 0.0, 10.0, dtype=dtype)
        assert v.dtype == dtype and np.isfinite(v).all() and (v > 0).all()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("material", ["copper", "glass", "nylon66", "oak", "foam"])
def test_finite_and_monotone_up_to_1e5_s(dtype: type, material: str) -> None:
    e = get_material(material).effusivity
    # cooling only (no heater, no loss): falls monotonically from V0 towards 0, never below
    cool = contact_excess(T_LONG, C, 0.0, 5e3, e, 0.0, 10.0, dtype=dtype)
    assert cool.dtype == dtype and np.isfinite(cool).all()
    assert cool[0] == pytest.approx(10.0) and (np.diff(cool.astype(np.float64)) <= 1e-5).all()
    assert (cool >= -1e-5).all()
    # large-time behaviour (physics.md): V0 erfcx(z) ~ V0 Mc / (e sqrt(pi t)), contact resistance aside
    assert cool[-1] == pytest.approx(10.0 * C / (e * math.sqrt(math.pi * 1e5)), rel=0.15)
    # heating only (V0 = 0): rises monotonically like 2 S sqrt(t) / (sqrt(pi) e) at long times
    heat = contact_excess(T_LONG, C, 0.0, 5e3, e, 0.0, 0.0, 100.0, dtype=dtype)
    assert np.isfinite(heat).all() and (np.diff(heat.astype(np.float64)) >= -1e-5).all()
    asymptote = 2 * 100.0 * math.sqrt(1e5) / (math.sqrt(math.pi) * e)
    assert heat[-1] == pytest.approx(asymptote, rel=0.15)
    # a sensor at its steady state with a loss: dips, then returns towards V0 (one minimum)
    steady = contact_excess(T_LONG, C, G, 5e3, e, 0.0, 10.0, dtype=dtype).astype(np.float64)
    assert np.isfinite(steady).all() and (steady <= 10.0 + 1e-4).all() and (steady >= -1e-4).all()
    signs = np.sign(np.diff(steady)[np.abs(np.diff(steady)) > 1e-5])
    assert (np.diff(signs) != 0).sum() <= 1


@pytest.mark.parametrize("material", ["aluminium", "marble", "pvc", "plywood"])
def test_float32_agrees_with_float64(material: str) -> None:
    e = get_material(material).effusivity
    ks = float(spreading_conductance(get_material(material).k_w_mk, 5e-3))
    for h in (3e3, 3e4, 4 * e**2 / C):
        a64 = contact_excess(T_LONG, C, G, h, e, ks, 10.0)
        a32 = contact_excess(T_LONG, C, G, h, e, ks, 10.0, dtype=np.float32)
        assert np.max(np.abs(a64 - a32)) < 2e-3


@given(
    log_c=st.floats(math.log(100.0), math.log(1e5)),
    log_g=st.floats(math.log(1e-3), math.log(1e3)),
    log_h=st.floats(math.log(10.0), math.log(1e8)),
    log_e=st.floats(math.log(10.0), math.log(5e4)),
    log_ks=st.floats(math.log(1e-3), math.log(1e5)),
    v0=st.floats(-30.0, 30.0),
)
def test_any_valid_parameters_give_a_bounded_finite_curve(
    log_c: float, log_g: float, log_h: float, log_e: float, log_ks: float, v0: float
) -> None:
    """With S = 0 the pixel only exchanges heat with bodies at 0 (the object) and V0 (its own
    steady state): v stays between them, starts at V0, for every t and both precisions."""
    args = (math.exp(log_c), math.exp(log_g), math.exp(log_h), math.exp(log_e), math.exp(log_ks), v0)
    for dtype in (np.float32, np.float64):
        v = contact_excess(T_LONG, *args, dtype=dtype).astype(np.float64)
        assert np.isfinite(v).all()
        tol = 2e-3 * max(abs(v0), 1.0)
        assert v[0] == pytest.approx(v0, abs=tol)
        assert (v >= min(0.0, v0) - tol).all() and (v <= max(0.0, v0) + tol).all()


def test_phi_series_and_direct_forms_join_smoothly() -> None:
    p = -np.geomspace(1e-4, 10.0, 400) * np.exp(1j * 0.6)
    t = np.full_like(p.real, 1.0)
    values = phi(p, t)
    # continuous across the series radius |p sqrt t| = 0.1, and the p -> 0 limit is 2 sqrt(t/pi)
    assert np.max(np.abs(np.diff(values))) < 0.05
    assert phi(np.array([0j]), np.array([4.0]))[0] == pytest.approx(2 * math.sqrt(4.0 / math.pi))


def test_recovery_after_release_takes_ln10_times_c_over_g() -> None:
    """The seed: 18 s to recover 90 % after an aluminium block is removed."""
    m = get_material("aluminium")
    model = ContactModel.create(C, G, 2e4, m.effusivity, spreading_conductance(m.k_w_mk, 5e-3), 10.0, 0.0)
    t = np.linspace(0.0, 60.0, 60001)
    v = touch_excess(t, model, np.array(1.0), np.array(3.0))
    assert v[0] == pytest.approx(10.0) and np.ptp(v[t < 1.0]) == 0.0
    v_release = v[np.searchsorted(t, 3.0)]
    recovered = t[np.argmax((t > 3.0) & (v >= v_release + 0.9 * (10.0 - v_release)))]
    assert recovered - 3.0 == pytest.approx(math.log(10.0) * C / G, rel=0.01)
    # with no loss the pixel heats linearly at S / C after release
    lone = recovery_excess(np.array([0.0, 2.0]), np.array(1.0), np.array(50.0), np.array(C), np.array(0.0))
    assert lone[1] - lone[0] == pytest.approx(2.0 * 50.0 / C)


def test_readout_noise_and_adc_are_separate_parts() -> None:
    readout = Readout(from_dict(ReadoutConfig, {"noise_k": 0.05, "adc_step_k": 0.1, "adc_range_c": [0.0, 50.0]}))
    clean = np.linspace(-5.0, 60.0, 2000)
    rng = np.random.default_rng(0)
    assert readout(clean, rng, noise=False) is clean
    out = readout(clean, rng)
    assert out.min() == 0.0 and out.max() == 50.0  # clipped at the ADC's range
    assert np.allclose(out / 0.1, np.round(out / 0.1))  # on the ADC's grid
    inside = (clean > 1) & (clean < 49)
    assert 0.03 < np.std(out[inside] - clean[inside]) < 0.08
