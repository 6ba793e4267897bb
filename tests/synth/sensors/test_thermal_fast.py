"""The fast thermal record (synth.sensors.thermal_fast) against the whole-record reference path."""

from __future__ import annotations

import numpy as np
import pytest

from synth.scene import load_scene
from synth.sensors.thermal import ContactModel, make_simulator, touch_excess
from synth.sensors.thermal.fast import SERIES_RADIUS, record_excess, series_terms


@pytest.mark.parametrize("name", ["thermal", "thermal_wns"])
def test_fast_clean_record_is_the_reference_to_rounding(name: str) -> None:
    scene = load_scene(name).with_noise(False)
    fast, ref = make_simulator(scene), make_simulator(scene, reference=True)
    d = fast.draw(300, np.random.default_rng(11))
    a, b = fast.clean_readings(d), ref.clean_readings(d)
    assert a.shape == b.shape and np.isfinite(a).all()
    assert np.abs(a - b).max() < 1e-9  # K; the curves swing by up to ~25 K


@pytest.mark.parametrize("name", ["thermal", "thermal_wns"])
def test_fast_simulator_gives_the_same_bytes(name: str) -> None:
    """Noise and ADC on: the readings (and every latent) are the reference path's, byte for byte."""
    scene = load_scene(name)
    fast = make_simulator(scene).simulate(70, np.random.default_rng(5))
    ref = make_simulator(scene, reference=True).simulate(70, np.random.default_rng(5))
    assert set(fast) == set(ref)
    for key in ref:
        assert np.array_equal(fast[key], ref[key]), key


def _model(n: int, rng: np.random.Generator, **fixed: float) -> ContactModel:
    params = {
        "heat_capacity": rng.uniform(200.0, 5000.0, n),
        "loss": rng.uniform(0.0, 400.0, n),
        "conductance": np.exp(rng.uniform(np.log(50.0), np.log(1e6), n)),
        "effusivity": np.exp(rng.uniform(np.log(30.0), np.log(40000.0), n)),
        "spreading": rng.uniform(0.0, 3000.0, n),
        "v0": rng.uniform(-30.0, 30.0, n),
        "heating": rng.uniform(-500.0, 500.0, n),
    }
    params.update({k: np.full(n, v) for k, v in fixed.items()})
    return ContactModel.create(**params)


@pytest.mark.parametrize(
    "fixed",
    [
        {},
        {"loss": 0.0, "spreading": 0.0, "heating": 0.0},
        {"loss": 0.0, "spreading": 0.0, "heating": 5000.0, "conductance": 1e6, "effusivity": 30000.0},
        {"conductance": 1e7},
        {"heat_capacity": 20.0},
    ],
    ids=["random", "seed-model", "seed-model-metal", "ideal-contact", "light-sensor"],
)
def test_record_excess_matches_touch_excess_over_wide_parameters(fixed: dict[str, float]) -> None:
    """Every root kind (series, real erfcx, complex erfcx), onsets before the record, releases at
    the onset and after the record, an uneven sampling rate."""
    rng = np.random.default_rng(3)
    n = 400
    model = _model(n, rng, **fixed)
    time_s = np.arange(173) / 33.0
    onset = rng.uniform(-0.5, 4.0, n)
    release = onset + rng.choice([0.0, 0.01, 0.7, 3.0, 9.0], n)
    fast = record_excess(time_s, model, onset, release)
    ref = touch_excess(time_s, model, onset, release)
    scale = np.abs(model.v0).max() + np.abs(model.heating / np.maximum(model.loss, 1.0)).max()
    assert np.abs(fast - ref).max() < 1e-9 * scale
    r, _ = model.poles
    reach = np.abs(r) * np.sqrt(np.maximum(release - onset, 0.0))[:, None]
    # the cases the parameters were chosen for do occur (the test must see every path)
    assert (reach <= SERIES_RADIUS).any() and (reach > SERIES_RADIUS).any()
    assert ((r.imag != 0) & (reach > SERIES_RADIUS)).any() or fixed


def test_series_terms_reach_the_truncation() -> None:
    assert series_terms(0.0) == 1
    assert series_terms(0.5) < series_terms(1.0) <= 40
    # the neglected term at |y| = 1 is below 1e-17
    from math import gamma

    m = series_terms(1.0)
    assert 1.0 / gamma((m + 1) / 2 + 1) < 1e-17


def test_recovery_of_mixed_blocks_with_and_without_loss() -> None:
    """One block holding pixels with G = 0 (a linear rise after release) and G > 0 (exponential
    relaxation), released before the end of the record: the recovery is the reference's."""
    rng = np.random.default_rng(9)
    n = 300
    model = _model(n, rng)
    loss = np.where(rng.random(n) < 0.5, 0.0, model.loss)
    model = ContactModel.create(
        model.heat_capacity, loss, model.conductance, model.effusivity, model.spreading, model.v0, model.heating
    )
    time_s = np.arange(325) / 50.0
    onset = rng.uniform(0.5, 2.0, n)
    release = onset + rng.uniform(0.0, 2.5, n)
    fast = record_excess(time_s, model, onset, release)
    ref = touch_excess(time_s, model, onset, release)
    after = time_s[None, :] > release[:, None]
    assert after.any(axis=1).all() and (loss == 0).any() and (loss > 0).any()
    scale = np.abs(model.v0).max() + np.abs(model.heating).max() * time_s[-1] / model.heat_capacity.min()
    assert np.abs(fast - ref).max() < 1e-9 * scale
    # a pixel without loss keeps rising (or falling) linearly after release: the G = 0 branch ran
    still = np.flatnonzero((loss == 0) & (np.abs(model.heating) > 1.0))[0]
    tail = fast[still, after[still]]
    assert np.allclose(np.diff(tail, 2), 0.0, atol=1e-9)
