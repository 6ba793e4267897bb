"""FSR single-frame fast path: triangulation and the one-press check on Python floats give the batch
path's answers (frame by frame against one batch call, on presses, two presses, flat indenters,
no contact and hand-made edge cases), and bad single frames still get the clear error."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from synth.config import replace
from synth.errors import InputError
from synth.scene import Scene, load_scene
from synth.sensors import fsr
from tactile_learn.estimators.classical.triangulation import FittedTriangulationEstimator, TriangulationEstimator
from tactile_learn.fsr_check import one_press_check

SCENE = load_scene("fsr6")
FULL_SCALE = fsr.Readout(SCENE.sensor.readout).full_scale


def _scene(**stimulus: object) -> Scene:
    config = SCENE.sensor
    for key, value in stimulus.items():
        config = replace(config, f"stimulus.{key}", value)
    return dataclasses.replace(SCENE, sensor=config)


def _frames() -> np.ndarray:
    """fsr6 frames (light and firm presses, no contact), two presses, flat indenters, and edge
    cases: zeros, codes just below full scale, one or two sensors loaded, equal loads, non-whole codes."""
    parts = [fsr.make_simulator(SCENE).simulate(500, np.random.default_rng(71))["readings"]]
    for seed, kind in ((72, "second_press_fraction"), (73, "flat_fraction")):
        sc = _scene(**{kind: 1.0, "no_contact_fraction": 0.0})
        parts.append(fsr.make_simulator(sc).simulate(120, np.random.default_rng(seed))["readings"])
    edge = np.zeros((8, fsr.N_SENSORS))
    edge[1] = FULL_SCALE - 1  # every sensor one code below saturation
    edge[2, 0] = 600  # one sensor loaded
    edge[3, [3, 4]] = 500  # two sensors of a triangle
    edge[4, [3, 4, 5]] = 420  # equal loads: the centroid (linear root)
    edge[5] = [3.0, 0.0, 0.0, 300.25, 280.5, 150.75]  # codes that are not whole numbers
    edge[6] = np.arange(6) * 150.0
    edge[7, 5] = FULL_SCALE - 1
    parts.append(edge)
    return np.ascontiguousarray(np.concatenate(parts), dtype=np.float32)


FRAMES = _frames()


@pytest.mark.parametrize("cls", [TriangulationEstimator, FittedTriangulationEstimator])
def test_one_frame_equals_the_batch_path(cls: type[TriangulationEstimator]) -> None:
    est = cls(SCENE).prepare()
    batch = est.predict(FRAMES)
    single = np.concatenate([est.predict(FRAMES[i : i + 1]) for i in range(len(FRAMES))])
    streamed = np.concatenate([est.predict_checked(FRAMES[i : i + 1]) for i in range(len(FRAMES))])
    np.testing.assert_allclose(single, batch, rtol=1e-6, atol=1e-5)
    np.testing.assert_array_equal(streamed, single)
    np.testing.assert_array_equal(single[:, 3:], batch[:, 3:])  # contact, inside and one-press flags
    # the frames exercise what they should: contacts, no contact, one-sensor fallbacks, flags both ways
    assert 0 < (single[:, 3] > 0.5).mean() < 1
    assert {0.0, 0.5, 1.0} <= set(single[:, 4].tolist())
    assert {0.0, 1.0} <= set(single[single[:, 3] > 0.5, 5].tolist())


def test_one_frame_of_a_calibrated_film_equals_the_batch_path() -> None:
    film = dataclasses.replace(SCENE.sensor.film, gains=(1.05, 0.95, 1.02, 0.97, 1.04, 0.96), gain_spread=0.0)
    scene = dataclasses.replace(SCENE, sensor=dataclasses.replace(SCENE.sensor, film=film))
    est = TriangulationEstimator(scene).prepare()
    frames = FRAMES[:200]
    single = np.concatenate([est.predict(frames[i : i + 1]) for i in range(len(frames))])
    np.testing.assert_allclose(single, est.predict(frames), rtol=1e-6, atol=1e-5)
    # the mapping to the nominal film was applied (a plain film's estimate differs)
    assert not np.allclose(single, TriangulationEstimator(SCENE).prepare().predict(frames))


def test_check_on_one_frame_equals_the_batch_check() -> None:
    """The flags agree, and the refined misfits agree to rounding from any start."""
    check = one_press_check(SCENE).prepare()
    est = TriangulationEstimator(SCENE).prepare()
    estimate = est.predict(FRAMES)[:, :5].copy()
    # shift half the estimates so that more frames need refining from a poor start
    estimate[::2, :2] += np.random.default_rng(5).normal(0.0, 3.0, (len(estimate[::2]), 2)).astype(np.float32)
    batch = check.p_one_press(FRAMES, estimate)
    single = np.array(
        [check.one_frame.p_one_press(f.tolist(), e.tolist()) for f, e in zip(FRAMES, estimate, strict=True)]
    )
    np.testing.assert_array_equal(single, batch)
    assert {0.0, 0.5, 1.0} <= set(single.tolist())
    # small batches refine both starts of their doubtful frames in one pass (a frame stops once
    # either start passes): the same flags
    small = [check.p_one_press(FRAMES[i : i + 16], estimate[i : i + 16]) for i in range(0, len(FRAMES), 16)]
    np.testing.assert_array_equal(np.concatenate(small), batch)

    rng = np.random.default_rng(6)
    measured = fsr.Readout(SCENE.sensor.readout).conductance_us(FRAMES[:100].astype(np.float64))
    starts = np.column_stack([rng.uniform(-25, 25, (100, 2)), rng.uniform(-1.0, 2.5, 100)])
    want = check._refined_misfit(measured, starts.copy())
    got = [check.one_frame.refined_misfit(m.tolist(), s.tolist(), -1.0) for m, s in zip(measured, starts, strict=True)]
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(
        [check.one_frame.conductance(*s) for s in starts.tolist()], check.conductance(starts), rtol=1e-12, atol=1e-12
    )


def test_conductance_beyond_the_table_uses_the_far_field() -> None:
    check = one_press_check(SCENE).prepare()
    far = np.array([[200.0, -150.0, 1.0], [0.0, 130.0, 2.0]])  # farther than the load table reaches
    np.testing.assert_allclose(
        [check.one_frame.conductance(*p) for p in far.tolist()], check.conductance(far), rtol=1e-12
    )


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (np.nan, "NaN or inf"),
        (np.inf, "NaN or inf"),
        (-1.0, "negative"),
        (float(FULL_SCALE), "saturated"),
        (float(FULL_SCALE) + 5.0, "saturated"),
    ],
)
def test_a_bad_single_frame_gets_the_clear_error(value: float, message: str) -> None:
    est = TriangulationEstimator(SCENE).prepare()
    frame = FRAMES[:1].copy()
    frame[0, 2] = value
    with pytest.raises(InputError, match=message):
        est.predict(frame)


def test_single_frames_of_other_forms_take_the_full_check() -> None:
    est = TriangulationEstimator(SCENE).prepare()
    frame = FRAMES[3:4]
    np.testing.assert_array_equal(est.predict(frame.astype(np.float64)), est.predict(frame))
    np.testing.assert_array_equal(est.predict(frame.tolist()), est.predict(frame))
    with pytest.raises(InputError, match="batch axis"):
        est.predict(frame[0])
    with pytest.raises(InputError, match="shape"):
        est.predict(np.zeros((1, 5), dtype=np.float32))


def test_the_checks_forward_model_is_the_films() -> None:
    """OnePressCheck.conductance (the load path and law written out) equals the film's own
    functions bit for bit, near the sensors, beyond the load table and at clipped forces."""
    check = one_press_check(SCENE).prepare()
    config, law, _, tip = check._model
    transfer, positions = check._path
    rng = np.random.default_rng(8)
    params = np.column_stack([rng.uniform(-90.0, 90.0, (3000, 2)), rng.uniform(-12.0, 8.0, 3000)])
    force = np.exp(np.clip(params[:, 2], -10.0, 6.0))
    distance = np.sqrt(((params[:, None, :2] - positions[None]) ** 2).sum(axis=2))
    radius = fsr.hertz_radius_mm(force, np.asarray(tip), config.layout)
    want = law.conductance_us(transfer.per_newton(distance, radius[:, None]) * force[:, None], 1.0)
    assert (distance > transfer.d_grid[-1]).any() and (distance < 2.0).any()
    np.testing.assert_array_equal(check.conductance(params), want)
    np.testing.assert_array_equal(check.conductance(params[:1]), want[:1])


def test_codes_outside_the_table_take_the_batch_inverse() -> None:
    """predict_checked trusts its caller; a code beyond the ADC's range still gets the batch
    path's answer rather than an index error."""
    est = TriangulationEstimator(SCENE).prepare()
    frame = np.array([[5000.0, 10.0, 0.0, 700.0, 650.0, 300.0]], dtype=np.float32)
    np.testing.assert_allclose(est.predict_checked(frame), est.predict_batch(frame), rtol=1e-6, atol=1e-5)
