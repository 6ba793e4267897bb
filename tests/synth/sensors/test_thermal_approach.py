"""The approach through a closing air gap (synth.sensors.thermal.approach) against an independent
finite-volume solution whose gap conductance varies in time (object cells on a graded grid, the
body and the thermistor's lags as extra states, stiff implicit integration), to 1 %."""

from __future__ import annotations

import numpy as np
import pytest

from synth.errors import InputError
from synth.materials import get_material
from synth.sensors.thermal.approach import K_AIR_W_MK, approach_term, gap_conductance
from synth.sensors.thermal.dynamics import ChannelModel, channel_terms
from tests.thermal_reference import varying_contact_reading

CASES = [
    # a heated channel (two lags) on a metal, a passive bead (one lag, a lower contact) on a wood
    ("aluminium", dict(heat_capacity=4000.0, loss=600.0, conductance=1000.0, lag1_s=0.8, lag2_s=0.5), 100e-6, 3e-3),
    ("oak", dict(heat_capacity=1500.0, loss=200.0, conductance=150.0, lag1_s=1.0), 200e-6, 1e-3),
]


@pytest.mark.parametrize(("material", "params", "gap_m", "speed"), CASES)
def test_approach_matches_the_finite_volume_solution(
    material: str, params: dict[str, float], gap_m: float, speed: float
) -> None:
    """The whole reading (approach + step contact at 0) against the finite-volume solution with
    the gap conductance varying in time: before and after the contact, to 1 % of the curve."""
    m = get_material(material)
    k, alpha = m.k_w_mk, m.diffusivity_mm2_s * 1e-6
    model = ChannelModel.create(effusivity=m.effusivity, **params)
    window = 1.5
    t = np.linspace(-1.2, 5.0, 125)
    h_contact = params["conductance"]

    def h_of_t(time: float) -> float:
        if time >= 0:
            return h_contact
        return float(gap_conductance(np.array([[time]]), np.array([h_contact]), gap_m, speed, window)[0, 0])

    lags = tuple(params[k_] for k_ in ("lag1_s", "lag2_s") if k_ in params)
    ref = varying_contact_reading(
        t,
        h_of_t,
        heat_capacity=params["heat_capacity"],
        loss=params["loss"],
        k_w_mk=k,
        diffusivity_m2_s=alpha,
        lags=lags,
        start_s=-window,
    )
    obj = channel_terms(model, t[None, :]).obj[0]
    precursor = approach_term(model, t[None, :], 0.0, gap_m, speed, window)[0]
    # the approach's own part (the reference minus the step contact) to 1 % of itself: a check
    # stricter than 1 % of the whole curve, of which it is 1-10 %
    own = ref - obj
    assert np.max(np.abs(own)) > 0.005 * np.max(np.abs(ref))
    assert np.max(np.abs(precursor - own)) <= 0.01 * np.max(np.abs(own))
    before = t < 0
    assert np.max(np.abs(precursor[before] - own[before])) <= 0.01 * np.max(np.abs(own[before]))


def test_gap_conductance_is_bounded_by_the_contact_and_grows_towards_it() -> None:
    tau = np.linspace(-2.5, 0.5, 301)[None, :]
    h = gap_conductance(tau, np.array([800.0]), 50e-6, 2e-3, 2.0)[0]
    inside = (tau[0] < 0) & (tau[0] >= -2.0)
    assert np.all(h[~inside] == 0.0)
    assert np.all(np.diff(h[inside]) > 0) and np.all(h[inside] < 800.0)
    assert h[inside][-1] == pytest.approx(1.0 / (1.0 / 800.0 + (50e-6 + 2e-3 * 0.01) / K_AIR_W_MK), rel=1e-2)


def test_approach_converges_with_the_grid_and_scales_with_the_gap() -> None:
    m = get_material("oak")
    model = ChannelModel.create(effusivity=m.effusivity, **CASES[1][1])
    t = np.linspace(-1.0, 4.0, 60)[None, :]
    coarse = approach_term(model, t, 0.1, 150e-6, 2e-3, fs=50.0)
    fine = approach_term(model, t, 0.1, 150e-6, 2e-3, fs=400.0)
    assert np.max(np.abs(coarse - fine)) <= 5e-3 * np.max(np.abs(fine))
    wider = approach_term(model, t, 0.1, 600e-6, 2e-3)
    assert np.max(np.abs(wider)) < np.max(np.abs(coarse))  # a wider gap passes less heat
    assert np.all(approach_term(model, t - 10.0, 0.1, 150e-6, 2e-3) == 0.0)  # nothing before the window


@pytest.mark.parametrize("bad", [0.0, -1e-4, float("nan"), float("inf")])
def test_bad_gap_or_speed_is_refused(bad: float) -> None:
    m = get_material("oak")
    model = ChannelModel.create(effusivity=m.effusivity, **CASES[1][1])
    with pytest.raises(InputError, match="gap_m"):
        approach_term(model, np.array([[0.1]]), 0.0, bad, 1e-3)
    with pytest.raises(InputError, match="speed_m_s"):
        approach_term(model, np.array([[0.1]]), 0.0, 1e-4, bad)


def test_a_controlled_channel_is_refused() -> None:
    m = get_material("oak")
    model = ChannelModel.create(effusivity=m.effusivity, kp=50.0, **CASES[1][1])
    with pytest.raises(InputError, match="controller"):
        approach_term(model, np.array([[0.1]]), 0.0, 1e-4, 1e-3)
