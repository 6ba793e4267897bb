"""Contact events (synth.sensors.thermal.contact_events): a contact conductance that steps while the
contact holds, against an independent finite-volume solution with the same stepping conductance
(object cells on a graded grid, the body and the thermistor's lags as extra states, Radau), to 1 %
of the events' own part of the curve."""

from __future__ import annotations

import numpy as np
import pytest

from synth.errors import InputError
from synth.materials import get_material
from synth.sensors.thermal.contact_events import conductance_multiplier, contact_event_terms
from synth.sensors.thermal.dynamics import ChannelModel, channel_terms
from tests.thermal_reference import varying_contact_reading

CASES = [
    # a heated channel (two lags) on a metal, events raising then lowering its contact; a passive
    # bead (one lag, a lower contact) on a wood, one event
    (
        "aluminium",
        dict(heat_capacity=4000.0, loss=600.0, conductance=1000.0, lag1_s=0.8, lag2_s=0.5),
        [1.3, 3.1],
        [1.4, 0.8],
    ),
    ("oak", dict(heat_capacity=1500.0, loss=200.0, conductance=150.0, lag1_s=1.0), [2.05], [0.6]),
]


def _reference(
    material: str, params: dict[str, float], times: list[float], factors: list[float], t: np.ndarray, **kw: object
) -> np.ndarray:
    m = get_material(material)
    h0 = params["conductance"]

    def h_of_t(time: float) -> float:
        return h0 * float(np.prod([f for tk, f in zip(times, factors, strict=True) if time > tk]))

    lags = tuple(params[k] for k in ("lag1_s", "lag2_s") if k in params)
    return varying_contact_reading(
        t,
        h_of_t,
        heat_capacity=params["heat_capacity"],
        loss=params["loss"],
        k_w_mk=m.k_w_mk,
        diffusivity_m2_s=m.diffusivity_mm2_s * 1e-6,
        lags=lags,
        start_s=0.0,
        **kw,  # type: ignore[arg-type]
    )


@pytest.mark.parametrize(("material", "params", "times", "factors"), CASES)
def test_events_match_the_finite_volume_solution(
    material: str, params: dict[str, float], times: list[float], factors: list[float]
) -> None:
    """A step contact at 0 whose conductance then steps at the events: the closed-form curve plus
    the events' part against the reference, to 1 % of the events' own part."""
    model = ChannelModel.create(effusivity=get_material(material).effusivity, **params)
    t = np.linspace(0.05, 6.0, 120)
    ref = _reference(material, params, times, factors, t)
    base = channel_terms(model, t[None, :]).obj[0]
    ev = contact_event_terms(model, t[None, :], 0.0, np.array([times]), np.array([factors])).obj[0]
    own = ref - base
    assert np.max(np.abs(own)) > 0.01 * np.max(np.abs(ref))  # the events are a visible part
    assert np.max(np.abs(ev - own)) <= 0.01 * np.max(np.abs(own))
    assert np.all(ev[t <= times[0]] == 0.0)


def test_heater_power_through_a_stepping_contact() -> None:
    """A heater power step at the onset (a drift's net heating) and one later, with V0 = 0: the
    events change how much of that heat leaves through the contact, to 1 % of their part."""
    material, params, times, factors = CASES[0]
    model = ChannelModel.create(effusivity=get_material(material).effusivity, **params)
    t = np.linspace(0.05, 6.0, 120)
    t_power = 1.8

    def power(time: float) -> float:
        return 100.0 + (-60.0 if time > t_power else 0.0)

    ref = _reference(material, params, times, factors, t, power_of_t=power, v0=0.0)
    terms = channel_terms(model, t[None, :], 0.0, np.array([t_power]))
    ev = contact_event_terms(model, t[None, :], 0.0, np.array([times]), np.array([factors]), np.array([t_power]))
    assert terms.power is not None and ev.power is not None
    base = 100.0 * _power_at(model, t, 0.0) - 60.0 * terms.power[0]
    closed = base + 100.0 * ev.heating[0] - 60.0 * ev.power[0]
    own = ref - base
    assert np.max(np.abs(own)) > 0.01 * np.max(np.abs(ref))
    assert np.max(np.abs(closed - ref)) <= 0.01 * np.max(np.abs(own))


def _power_at(model: ChannelModel, t: np.ndarray, at: float) -> np.ndarray:
    terms = channel_terms(model, t[None, :], 0.0, np.array([at]))
    assert terms.power is not None
    return terms.power[0]


def test_no_event_or_a_factor_of_one_changes_nothing_and_the_grid_converges() -> None:
    material, params, times, factors = CASES[0]
    model = ChannelModel.create(effusivity=get_material(material).effusivity, **params)
    t = np.linspace(-0.3, 6.0, 80)[None, :]
    none = contact_event_terms(model, t, 0.1, np.array([[np.nan]]), np.array([[2.0]]))
    assert np.all(none.obj == 0.0) and np.all(none.heating == 0.0) and none.power is None
    one = contact_event_terms(model, t, 0.1, np.array([[1.5]]), np.array([[1.0]]))
    assert np.max(np.abs(one.obj)) < 1e-12
    coarse = contact_event_terms(model, t, 0.1, np.array([times]), np.array([factors]), fs=25.0).obj
    fine = contact_event_terms(model, t, 0.1, np.array([times]), np.array([factors]), fs=200.0).obj
    assert np.max(np.abs(coarse - fine)) <= 0.01 * np.max(np.abs(fine))
    # a larger contact draws more heat: a factor above 1 lowers the reading further (V0 > 0)
    assert fine[0, -1] < 0


def test_multiplier_is_the_product_of_the_factors_so_far() -> None:
    t = np.array([[0.5, 1.5, 2.5, 3.5]])
    m = conductance_multiplier(t, np.array([[3.0, 1.0, np.nan]]), np.array([[0.5, 2.0, 7.0]]))
    assert m.tolist() == [[1.0, 2.0, 2.0, 1.0]]


@pytest.mark.parametrize(
    ("times", "factors", "match"),
    [
        ([[1.0]], [[0.0]], "event_factor"),
        ([[1.0]], [[np.nan]], "event_factor"),
        ([[-0.5]], [[1.2]], "after"),
        ([[np.inf]], [[1.2]], "finite"),
        ([[1.0, 2.0]], [[1.2]], "must both"),
    ],
)
def test_bad_events_are_refused(times: list[list[float]], factors: list[list[float]], match: str) -> None:
    model = ChannelModel.create(effusivity=get_material("oak").effusivity, **CASES[1][1])
    with pytest.raises(InputError, match=match):
        contact_event_terms(model, np.array([[0.5, 1.0]]), 0.0, np.array(times), np.array(factors))
