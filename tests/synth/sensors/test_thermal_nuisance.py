"""Per-touch nuisance terms of a real channel (synth.sensors.thermal.dynamics.nuisance_terms): an
object whose temperature is not uniform with depth and heater power steps at several times, each
against the independent finite-volume + Radau solution (tests/thermal_reference.py), to 1 %."""

from __future__ import annotations

import numpy as np
import pytest

from synth.errors import InputError
from synth.materials import get_material
from synth.sensors.thermal.dynamics import ChannelModel, channel_terms, nuisance_terms
from tests.thermal_reference import channel_of_material, reference_channel, relative_max_error

T = np.geomspace(0.02, 8.0, 60)

#: slabs (the reference's linear initial profile is steady only there): a heated channel with two
#: lags, a passive bead with one, a bare body
CASES = [
    ("aluminium", dict(heat_capacity=3000.0, loss=50.0, conductance=700.0, lag1_s=0.8, lag2_s=0.3)),
    ("oak", dict(heat_capacity=500.0, loss=20.0, conductance=300.0, lag1_s=0.3)),
    ("pine", dict(heat_capacity=2000.0, loss=250.0, conductance=2000.0)),
]


@pytest.mark.parametrize(("material", "params"), CASES)
@pytest.mark.parametrize("gradient", [-60.0, 25.0])
def test_object_gradient_flux_matches_the_reference(material: str, params: dict[str, float], gradient: float) -> None:
    """An object whose temperature changes with depth (K/m) before contact: ``F = k g`` reaches the
    surface, and the reading moves by ``F`` times the flux term."""
    model, k, alpha = channel_of_material(material, params)
    flux = nuisance_terms(model, T[None, :]).flux[0]
    ref = reference_channel(T, k_w_mk=k, diffusivity_m2_s=alpha, v0=0.0, gradient_k_m=gradient, **params)
    assert relative_max_error(k * gradient * flux, ref) <= 0.01
    # with an object temperature step as well: the sum (linear)
    obj = channel_terms(model, T[None, :]).obj[0]
    both = reference_channel(T, k_w_mk=k, diffusivity_m2_s=alpha, v0=4.0, gradient_k_m=gradient, **params)
    assert relative_max_error(4.0 * obj + k * gradient * flux, both) <= 0.01


@pytest.mark.parametrize(("material", "params"), CASES)
def test_heater_steps_at_several_times_match_the_reference(material: str, params: dict[str, float]) -> None:
    model, k, alpha = channel_of_material(material, params)
    terms = nuisance_terms(model, T[None, :], 0.0, (np.array([0.0]), np.array([0.7])))
    for j, (amount, at) in enumerate(((2000.0, 0.0), (-1500.0, 0.7))):
        ref = reference_channel(
            T, k_w_mk=k, diffusivity_m2_s=alpha, v0=0.0, power_step=amount, power_step_s=at, **params
        )
        if at == 0.0:  # the reference starts a step at 0 only when it is given as a positive time
            ref = reference_channel(
                T, k_w_mk=k, diffusivity_m2_s=alpha, v0=0.0, power_step=amount, power_step_s=1e-9, **params
            )
        assert relative_max_error(amount * terms.steps[j, 0], ref) <= 0.01
    # the same step as channel_terms' single heater change
    single = channel_terms(model, T[None, :], 0.0, np.array([0.7])).power
    assert single is not None
    assert np.allclose(terms.steps[1], single, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("ramp", [0.1, 0.8])
def test_flux_builds_up_with_the_contact(ramp: float) -> None:
    """With a contact that builds up over ``ramp``: the mean of step fluxes starting over the ramp."""
    model, _, _ = channel_of_material("oak", dict(CASES[1][1]))
    t = np.linspace(-0.5, 6.0, 131)
    smooth = nuisance_terms(model, t[None, :], ramp).flux[0]
    shifts = (np.arange(200) + 0.5) / 200 * ramp
    steps = np.mean([nuisance_terms(model, (t - s)[None, :]).flux[0] for s in shifts], axis=0)
    assert np.max(np.abs(smooth - steps)) <= 0.01 * np.max(np.abs(steps))
    assert np.all(smooth[t <= 0] == 0.0)


def test_controlled_channel_flux_settles_back() -> None:
    """A PI-held channel: the integral action brings the reading back to its set point under a
    constant flux (the flux term's extra factor ``q^2``), so the term decays to 0."""
    model = ChannelModel.create(
        heat_capacity=2000.0,
        loss=25.0,
        conductance=3000.0,
        effusivity=get_material("oak").effusivity,
        lag1_s=0.4,
        kp=2000.0,
        ki=3000.0,
    )
    flux = nuisance_terms(model, np.array([[0.5, 200.0]])).flux[0]
    assert flux[0] > 0 and abs(flux[1]) < 0.02 * flux[0]


def test_negative_ramp_is_refused() -> None:
    model, _, _ = channel_of_material("oak", dict(CASES[1][1]))
    with pytest.raises(InputError, match="ramp_s"):
        nuisance_terms(model, T[None, :], -0.1)
