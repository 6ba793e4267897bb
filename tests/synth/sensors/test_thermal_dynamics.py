"""A real thermistor channel (lags, heater control or switch-off, drift, contact build-up, passive
channel): every closed form of synth.sensors.thermal_dynamics against an independent finite-volume
+ Radau solution (tests/thermal_reference.py), to 1 % or better."""

from __future__ import annotations

import numpy as np
import pytest

from synth.errors import InputError
from synth.sensors.thermal import phi
from synth.sensors.thermal.dynamics import ChannelModel, channel_response, channel_terms, phi_integral
from tests.thermal_reference import channel_of_material, reference_channel, relative_max_error

T = np.geomspace(0.02, 8.0, 60)

#: (material, channel parameters): heated open loop with two lags and spreading, a passive bead,
#: a heated channel held by a PI controller, equal lags (a double root, split)
CASES = [
    ("aluminium", dict(heat_capacity=3000.0, loss=50.0, conductance=700.0, spreading=100.0, lag1_s=0.8, lag2_s=0.3)),
    ("oak", dict(heat_capacity=500.0, loss=20.0, conductance=300.0, spreading=30.0, lag1_s=0.3)),
    ("oak", dict(heat_capacity=2000.0, loss=250.0, conductance=2000.0)),
    (
        "mild_steel",
        dict(heat_capacity=2000.0, loss=25.0, conductance=3000.0, lag1_s=0.4, lag2_s=0.2, kp=2000.0, ki=3000.0),
    ),
    ("pine", dict(heat_capacity=1500.0, loss=40.0, conductance=800.0, spreading=20.0, lag1_s=0.5, lag2_s=0.5)),
]


@pytest.mark.parametrize(("material", "params"), CASES)
def test_object_step_matches_the_reference(material: str, params: dict[str, float]) -> None:
    model, k, alpha = channel_of_material(material, params)
    closed = channel_response(model, np.array([7.0]), T[None, :])[0]
    ref = reference_channel(T, k_w_mk=k, diffusivity_m2_s=alpha, v0=7.0, **params)
    assert relative_max_error(closed, ref) <= 0.01


@pytest.mark.parametrize(("material", "params"), [c for c in CASES if "kp" not in c[1]])
def test_drift_and_heater_switch_off_match_the_reference(material: str, params: dict[str, float]) -> None:
    """A reading drifting at 0.2 K/s before contact (the net heating goes on, the lags' lead decays)
    and a heater switched off 0.4 s into the contact."""
    model, k, alpha = channel_of_material(material, params)
    terms = channel_terms(model, T[None, :], 0.0, np.array([0.4]))
    ref_drift = reference_channel(T, k_w_mk=k, diffusivity_m2_s=alpha, v0=0.0, drift_k_s=0.2, **params)
    assert relative_max_error(0.2 * terms.drift[0], ref_drift) <= 0.01
    assert terms.power is not None
    ref_power = reference_channel(
        T, k_w_mk=k, diffusivity_m2_s=alpha, v0=0.0, power_step=-1500.0, power_step_s=0.4, **params
    )
    assert relative_max_error(-1500.0 * terms.power[0], ref_power) <= 0.01
    # the whole reading is their sum (linear): object, drift and switch-off together
    both = reference_channel(
        T, k_w_mk=k, diffusivity_m2_s=alpha, v0=5.0, drift_k_s=0.2, power_step=-1500.0, power_step_s=0.4, **params
    )
    # (V0 is the body's temperature minus the object's at the onset, as in the reference)
    closed = 0.2 * terms.drift[0] + 5.0 * terms.obj[0] - 1500.0 * terms.power[0]
    assert relative_max_error(closed, both) <= 0.01


def test_drift_is_continuous_at_the_onset_and_a_ramp_before_it() -> None:
    model, _, _ = channel_of_material("oak", dict(CASES[0][1]))
    t = np.linspace(-1.0, 1.0, 401)[None, :]
    drift = channel_terms(model, t).drift[0]
    assert np.allclose(drift[t[0] <= 0], t[0][t[0] <= 0])
    assert np.max(np.abs(np.diff(drift))) < 2 * (t[0, 1] - t[0, 0])  # no jump at t = 0


@pytest.mark.parametrize("ramp", [0.05, 0.4, 1.5])
def test_contact_build_up_is_the_average_of_staggered_step_contacts(ramp: float) -> None:
    """The build-up term is defined as the mean of step contacts starting uniformly over the ramp:
    its closed form (Psi differences) against 200 shifted step responses."""
    model, _, _ = channel_of_material("oak", dict(CASES[1][1]))
    t = np.linspace(-0.5, 6.0, 131)
    smooth = channel_terms(model, t[None, :], ramp).obj[0]
    shifts = (np.arange(200) + 0.5) / 200 * ramp
    steps = np.mean([channel_response(model, np.array([1.0]), (t - s)[None, :])[0] for s in shifts], axis=0)
    assert np.max(np.abs(smooth - steps)) <= 0.01 * np.max(np.abs(steps))


@pytest.mark.parametrize("p", [-3.0 + 1.0j, -0.2 + 0j, 0.5 + 4.0j, -20.0 + 0j, 1e-3j, -1e-4 + 0j])
def test_phi_integral_is_the_integral_of_phi(p: complex) -> None:
    t = np.linspace(0.0, 5.0, 20001)
    values = phi(np.array([p]), t)
    trapezoid = np.concatenate([[0.0], np.cumsum((values[1:] + values[:-1]) / 2 * np.diff(t))])
    closed = phi_integral(np.array([p]), t)
    assert np.max(np.abs(closed - trapezoid)) <= 1e-5 * np.max(np.abs(trapezoid))
    # the series and the direct formula meet smoothly (|y| = 0.5 is where they switch)
    assert np.isfinite(closed).all()


def test_unstable_controller_is_refused() -> None:
    model = ChannelModel.create(
        heat_capacity=100.0, loss=1.0, conductance=500.0, effusivity=400.0, lag1_s=2.0, lag2_s=1.0, kp=1e6, ki=1e6
    )
    with pytest.raises(InputError, match="unstable channel"):
        channel_terms(model, T[None, :])


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(InputError, match="conductance"):
        ChannelModel.create(heat_capacity=1.0, loss=1.0, conductance=-1.0, effusivity=400.0)
    model, _, _ = channel_of_material("oak", dict(CASES[1][1]))
    with pytest.raises(InputError, match="ramp_s"):
        channel_terms(model, T[None, :], -0.1)
