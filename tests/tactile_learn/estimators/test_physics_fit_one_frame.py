"""The physics fit's one-curve path (batch 1): the batch path's model, fit and probabilities to
rounding, and the batch path fitting only the curves with an onset."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from synth.errors import InputError
from synth.scene import Scene, load_scene
from synth.sensors.thermal import ContactModel, make_simulator
from tactile_learn.estimators.classical import physics_fit_one_frame as one
from tactile_learn.estimators.classical.physics_fit import (
    _BOUNDS,
    _STEPS,
    PhysicsFitEstimator,
    contact_drop,
    fit_curves,
)
from tactile_learn.tasks.thermal import ThermalTask
from tests.tactile_learn.test_thermal_real import robot_scene

TASK = ThermalTask()


def touches(scene: Scene, n: int, seed: int) -> np.ndarray:
    """Inputs of ``n`` simulated touches (every pixel's window) as the task gives them."""
    data = make_simulator(scene).simulate(n, np.random.default_rng(seed))
    return np.asarray(TASK.example_inputs(data, scene), dtype=np.float32)


def parameter_sets(n: int, seed: int) -> tuple[np.ndarray, ...]:
    """``C, G, e, H, k_s`` over the fit's parameter box (and the sensors' range)."""
    rng = np.random.default_rng(seed)
    return (
        rng.uniform(200.0, 5000.0, n),
        rng.uniform(0.0, 400.0, n),
        np.exp(rng.uniform(*_BOUNDS[2], n)),
        np.exp(rng.uniform(*_BOUNDS[3], n)),
        np.exp(rng.uniform(*_BOUNDS[4], n)),
    )


def test_one_curve_poles_are_the_contact_models() -> None:
    c, g, e, h, ks = parameter_sets(400, seed=3)
    roots, weights = ContactModel.create(c, g, h, e, ks, 1.0, 0.0).poles
    taken = 0
    for i in range(len(c)):
        found = one.one_curve_poles(c[i], g[i], h[i], e[i], ks[i])
        if found is None:  # the caller takes ContactModel then
            continue
        taken += 1
        # the same roots in the same order, to rounding
        np.testing.assert_allclose(found[0], roots[i], rtol=1e-12, atol=1e-12 * np.abs(roots[i]).max())
        np.testing.assert_allclose(found[1], weights[i], rtol=1e-9, atol=1e-12 * np.abs(weights[i]).max())
    assert taken > 350


def test_a_double_root_is_left_to_the_contact_model() -> None:
    """D(q) = C e (q + 1)^2 (q + 2) (e = 1, H = 3.8, k_s = 0.2, C = H^2 / 18, G = 5 C - H): the
    batch path splits the double root by nudging H, the one-curve poles leave it to that."""
    h, ks = 3.8, 0.2
    c = h * h / 18.0
    g = 5.0 * c - h
    assert one.one_curve_poles(c, g, h, 1.0, ks) is None
    poles = one._poles(c, g, [[1.0, h, ks]])
    roots, weights = poles.roots, poles.weights
    assert not poles.pairs
    expect = ContactModel.create(c, g, h, 1.0, ks, 1.0, 0.0).poles
    assert np.array_equal(roots[0], expect[0]) and np.array_equal(weights[0], expect[1])


def test_one_curve_drops_are_the_batch_models() -> None:
    """The model of the one-curve path (series where |y| < 0.1, erfcx over the root elsewhere,
    from one sample before the onset on) against contact_drop, over the parameter box."""
    c, g, e, h, ks = parameter_sets(60, seed=4)
    fs = 50.0
    t = np.arange(125) / fs
    rng = np.random.default_rng(5)
    t0 = rng.uniform(-1.0 / fs, 2.4, len(c))
    paired = 0
    for i in range(len(c)):
        params = [[e[i], h[i], ks[i]], [e[i] * 1.0001, h[i], ks[i]]]
        poles = one._poles(c[i], g[i], params)
        ours = one._drops(fs, t, np.array([t0[i], t0[i] + 0.0004]), *poles)
        if poles.pairs:  # a real root and a conjugate pair: the same as the three roots summed
            general = one._drops(fs, t, np.array([t0[i], t0[i] + 0.0004]), *poles[:3], False)
            np.testing.assert_allclose(ours, general, rtol=0, atol=1e-14)
            paired += 1
        ref = contact_drop(
            t[None, :] - np.array([[t0[i]], [t0[i] + 0.0004]]),
            np.full(2, c[i]),
            np.full(2, g[i]),
            np.array([e[i], e[i] * 1.0001]),
            np.full(2, h[i]),
            np.full(2, ks[i]),
        )
        np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-12)
        assert (ours[:, : max(math.floor(t0[i] * fs), 0)] == 0).all()
    assert 0 < paired < len(c)  # both kinds of sets (three real roots: the general sum)


def test_poles_fall_back_to_the_contact_model(monkeypatch: pytest.MonkeyPatch) -> None:
    c, g, e, h, ks = parameter_sets(5, seed=6)
    params = [[e[i], h[i], ks[i]] for i in range(5)]
    direct = one._poles(c[0], g[0], params)
    monkeypatch.setattr(one, "one_curve_poles", lambda *args: None)
    fallback = one._poles(c[0], g[0], params)
    for ours, theirs in zip(direct[:3], fallback[:3], strict=True):
        np.testing.assert_allclose(ours, theirs, rtol=1e-9)
    assert direct.pairs and not fallback.pairs  # the fallback's roots go through the general sum


@pytest.mark.parametrize("scene_name", ["thermal", "robot", "no_spreading"])
def test_batch_1_gives_the_batch_probabilities(scene_name: str) -> None:
    """Every held-out curve (touched pixels and pixels the touch missed) at batch 1 against the
    batch: the fits differ in rounding only (a complex product in Python and in numpy's SIMD
    loops), which 25 iterations do not amplify."""
    if scene_name == "robot":
        scene: Scene = robot_scene()  # type: ignore[assignment]
    else:
        scene = load_scene("thermal")
    if scene_name == "no_spreading":
        contact = dataclasses.replace(scene.sensor.contact, spreading=False)  # type: ignore[attr-defined]
        scene = dataclasses.replace(scene, sensor=dataclasses.replace(scene.sensor, contact=contact))  # type: ignore[type-var]
    x = touches(scene, 2, seed=61)
    est = PhysicsFitEstimator(scene, chunk=9).prepare()
    batch = est.predict_proba(x)
    singles = np.concatenate([est.predict_proba(x[i : i + 1]) for i in range(len(x))])
    np.testing.assert_allclose(singles, batch, rtol=0, atol=1e-6)
    assert (singles.argmax(axis=1) == batch.argmax(axis=1)).all()
    assert singles.dtype == batch.dtype == np.float32


def test_one_curve_fit_is_the_batch_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    """From the batch's initial values, fit_one_curve ends where fit_curves does."""
    import tactile_learn.estimators.classical.physics_fit as physics_fit

    scene = load_scene("thermal")
    est = PhysicsFitEstimator(scene).prepare()
    x = touches(scene, 2, seed=62).astype(np.float64)
    c, g, v0_range = est._sensor(len(x))
    seen: list[tuple[np.ndarray, ...]] = []

    def spy(*args: object, **kwargs: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        seen.append(args[4:6])  # type: ignore[arg-type]  # the initial values and noise levels
        return fit_curves(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(physics_fit, "fit_curves", spy)
    fit = est.fit_batch(x, c, g, v0_range)
    (init, sigma), fitted = seen[0], np.flatnonzero(fit.detected)
    assert len(fitted) > 10
    cfg = scene.sensor
    for n, i in enumerate(fitted[:12]):
        theta, cov, chi2 = one.fit_one_curve(
            x[i], cfg, c[i], g[i], init[n], sigma[n], tuple(v0_range[i]), est.iterations,
            cfg.contact.spreading, _BOUNDS, _STEPS,
        )  # fmt: skip
        # rounding moves the end point along the cost's flat directions (log H when the contact
        # conductance barely limits the drop) by ~1e-6; the fit's cost and covariance stay put
        np.testing.assert_allclose(theta, fit.theta[i], rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(chi2, fit.chi2[i], rtol=1e-7)
        np.testing.assert_allclose(cov, fit.cov[i], rtol=1e-3, atol=1e-6 * np.abs(fit.cov[i]).max())


def test_curves_without_an_onset_are_none_and_leave_the_others_alone() -> None:
    scene = load_scene("thermal")
    est = PhysicsFitEstimator(scene).prepare()
    x = touches(scene, 1, seed=63)
    flat = np.full_like(x[:2], 35.0)  # a sensor at rest: no onset
    mixed = np.concatenate([x, flat])
    out = est.predict_proba(mixed)
    assert np.array_equal(out[: len(x)], est.predict_proba(x))
    none = np.zeros(out.shape[1], dtype=np.float32)
    none[-1] = 1.0
    assert np.array_equal(out[len(x) :], np.stack([none, none]))
    assert np.array_equal(est.predict_proba(flat[:1])[0], none)  # batch 1: the same


def test_batch_1_refuses_bad_input() -> None:
    scene = load_scene("thermal")
    est = PhysicsFitEstimator(scene).prepare()
    x = touches(scene, 1, seed=64)[:1].copy()
    x[0, 5] = np.nan
    with pytest.raises(InputError, match=r"finite|NaN"):
        est.predict_proba(x)
