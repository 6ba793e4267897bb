"""The contact precursor of a real channel (synth.sensors.thermal.dynamics.nuisance_terms'
``precursor``): part of the contact building up over the seconds before the onset, against the
independent finite-volume + Radau solution (tests/thermal_reference.py) averaged over the early
contacts' start times, to 1 %."""

from __future__ import annotations

import numpy as np
import pytest

from synth.errors import InputError
from synth.materials import get_material
from synth.sensors.thermal.dynamics import ChannelModel, channel_terms, nuisance_terms
from tests.thermal_reference import reference_channel

#: a heated channel with two lags on a metal and a passive bead with one on a wood (slabs)
CASES = [
    ("aluminium", dict(heat_capacity=3000.0, loss=50.0, conductance=700.0, lag1_s=0.8, lag2_s=0.3)),
    ("oak", dict(heat_capacity=500.0, loss=20.0, conductance=300.0, lag1_s=0.3)),
]


@pytest.mark.parametrize(("material", "params"), CASES)
def test_precursor_matches_the_reference(material: str, params: dict[str, float]) -> None:
    """``obj_early - obj``: the mean of step contacts starting over the ``precursor_s`` before the
    onset (Gauss-Legendre over the start times, each a reference solution) minus the step at it."""
    m = get_material(material)
    k, alpha = m.k_w_mk, m.diffusivity_mm2_s * 1e-6
    model = ChannelModel.create(effusivity=m.effusivity, **params)
    early_s = 0.6
    t = np.geomspace(0.02, 6.0, 40)
    closed = nuisance_terms(model, t[None, :], 0.0, (), early_s).precursor
    assert closed is not None
    nodes, weights = np.polynomial.legendre.leggauss(10)
    starts = -0.5 * early_s * (nodes + 1.0)  # in [-early_s, 0]
    early = sum(
        w / 2 * reference_channel(t - s, k_w_mk=k, diffusivity_m2_s=alpha, v0=1.0, **params)
        for s, w in zip(starts, weights, strict=True)
    )
    ref = early - reference_channel(t, k_w_mk=k, diffusivity_m2_s=alpha, v0=1.0, **params)
    # the reference gives the deviation for V0 = 1 K the same way channel_terms' obj does
    assert np.max(np.abs(closed[0] - ref)) <= 0.01 * np.max(np.abs(ref))


def test_precursor_is_the_mean_of_early_step_contacts_and_starts_early() -> None:
    """On a grid that crosses the onset: the closed form equals the numerical mean of closed-form
    step contacts (a second, independent route), is 0 before the precursor's start and not after."""
    m = get_material("oak")
    model = ChannelModel.create(effusivity=m.effusivity, **CASES[1][1])
    t = np.linspace(-1.5, 5.0, 131)
    ramp, early_s = 0.1, 0.8
    closed = nuisance_terms(model, t[None, :], ramp, (), early_s).precursor
    assert closed is not None
    shifts = -(np.arange(400) + 0.5) / 400 * early_s
    mean_early = np.mean([channel_terms(model, (t - s)[None, :]).obj[0] for s in shifts], axis=0)
    numeric = mean_early - channel_terms(model, t[None, :], ramp).obj[0]
    assert np.max(np.abs(closed[0] - numeric)) <= 1e-3 * np.max(np.abs(numeric))
    assert np.all(closed[0][t <= -early_s] == 0.0)
    assert np.any(closed[0][(t > -early_s) & (t < 0)] != 0.0)


def test_no_precursor_leaves_the_other_terms_unchanged() -> None:
    m = get_material("aluminium")
    model = ChannelModel.create(effusivity=m.effusivity, **CASES[0][1])
    t = np.linspace(-0.5, 6.0, 50)[None, :]
    base = nuisance_terms(model, t, 0.2, (np.array([0.5]),))
    more = nuisance_terms(model, t, 0.2, (np.array([0.5]),), 0.7)
    assert base.precursor is None and more.precursor is not None
    assert np.array_equal(base.flux, more.flux) and np.array_equal(base.steps, more.steps)


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf")])
def test_bad_precursor_length_is_refused(bad: float) -> None:
    m = get_material("oak")
    model = ChannelModel.create(effusivity=m.effusivity, **CASES[1][1])
    with pytest.raises(InputError, match="precursor_s"):
        nuisance_terms(model, np.array([[0.1, 1.0]]), 0.0, (), bad)
