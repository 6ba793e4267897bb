"""FSR single frames, seventh pass: a frame with one valid sensor is answered from that sensor at once
(the contact on it with its load over the on-axis load per newton: what every candidate triangle's
fallback gives), bit for bit as the batch path; the single-frame answer is one function for the
whole frame and still equals the batch path on presses, two presses and flat indenters."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from synth.config import replace
from synth.scene import Scene, load_scene
from synth.sensors import fsr
from tactile_learn.estimators.classical.triangulation import FittedTriangulationEstimator, TriangulationEstimator
from tactile_learn.frame_stream import FrameStream

SCENE = load_scene("fsr6")


def _one_sensor_frames(est: TriangulationEstimator, seed: int = 5) -> np.ndarray:
    """Frames whose only valid sensor is each sensor in turn, with loads from just above the valid
    load to firm, the others at codes below it (0 or a light load)."""
    loads = np.asarray(est.one_frame_.loads_of_codes)
    above = np.flatnonzero(loads >= est.one_frame_.min_load)
    below = np.flatnonzero(loads < est.one_frame_.min_load)
    rng = np.random.default_rng(seed)
    frames = []
    for k in range(fsr.N_SENSORS):
        for code in np.concatenate([above[:3], rng.choice(above, 12)]):
            frame = rng.choice(below, fsr.N_SENSORS).astype(np.float64)
            frame[rng.random(fsr.N_SENSORS) < 0.5] = 0.0
            frame[k] = code
            frames.append(frame)
    return np.asarray(frames, dtype=np.float32)


@pytest.mark.parametrize("cls", [TriangulationEstimator, FittedTriangulationEstimator])
def test_a_frame_with_one_valid_sensor_is_the_batch_paths_answer(cls: type[TriangulationEstimator]) -> None:
    est = cls(SCENE).prepare()
    frames = _one_sensor_frames(est)
    batch = est.predict(frames)
    single = np.concatenate([est.predict(frames[i : i + 1]) for i in range(len(frames))])
    runner = est.frame_runner()
    by_runner = np.concatenate([runner(frames[i : i + 1]) for i in range(len(frames))])
    np.testing.assert_array_equal(single, batch)  # the same operations: bit for bit
    np.testing.assert_array_equal(by_runner, batch)
    positions = fsr.sensor_positions(SCENE.sensor.layout).astype(np.float32)
    sensor = np.repeat(np.arange(fsr.N_SENSORS), len(frames) // fsr.N_SENSORS)
    np.testing.assert_array_equal(single[:, :2], positions[sensor])  # on the sensor
    assert (single[:, 2] > 0).all() and (single[:, 3] == 1).all()
    assert (single[:, 4] == 0.5).all() and (single[:, 5] == 0.5).all()  # inside or out: undecided, not checked


def test_one_valid_sensor_keeps_one_candidate_triangle() -> None:
    one = TriangulationEstimator(SCENE).prepare().one_frame_
    positions = fsr.sensor_positions(SCENE.sensor.layout)
    tris = [set(t) for t in fsr.TRIANGLES]
    for mask in range(1 << fsr.N_SENSORS):
        lone = one.lone_sensor[mask]
        if bin(mask).count("1") != 1:
            assert lone is None
            if mask:  # every triangle with the most valid sensors stays a candidate
                counts = [sum(mask >> i & 1 for i in t) for t in tris]
                assert one.candidates[mask] == tuple(t for t, n in enumerate(counts) if n == max(counts))
            continue
        k = mask.bit_length() - 1
        assert lone is not None and lone[0] == k and lone[1:] == tuple(positions[k])
        (t,) = one.candidates[mask]
        assert k in tris[t]


def _scene(**stimulus: object) -> Scene:
    config = SCENE.sensor
    for key, value in stimulus.items():
        config = replace(config, f"stimulus.{key}", value)
    return dataclasses.replace(SCENE, sensor=config)


@pytest.mark.parametrize("cls", [TriangulationEstimator, FittedTriangulationEstimator])
def test_single_frames_and_streams_flag_as_the_batch_path(cls: type[TriangulationEstimator]) -> None:
    """Presses, two presses and flat indenters anywhere: the one-frame answer's columns from the
    contact on equal the batch path's (positions to rounding), by ``predict`` and by a stream."""
    parts = [fsr.make_simulator(SCENE).simulate(300, np.random.default_rng(91))["readings"]]
    for seed, kind in ((92, "second_press_fraction"), (93, "flat_fraction")):
        scene = _scene(**{kind: 1.0, "no_contact_fraction": 0.0})
        parts.append(fsr.make_simulator(scene).simulate(150, np.random.default_rng(seed))["readings"])
    frames = np.ascontiguousarray(np.concatenate(parts), dtype=np.float32)
    est = cls(SCENE).prepare()
    batch = est.predict(frames)
    single = np.concatenate([est.predict(frames[i : i + 1]) for i in range(len(frames))])
    stream = FrameStream(est)
    streamed = np.concatenate([stream.predict(frames[i : i + 1]) for i in range(len(frames))])
    np.testing.assert_array_equal(single[:, 3:], batch[:, 3:])
    np.testing.assert_allclose(single, batch, rtol=1e-6, atol=1e-5)
    np.testing.assert_array_equal(streamed, single)
    flagged = single[:, 5] < 0.5
    assert flagged[300:].mean() > 0.2 and flagged[:300][single[:300, 4] == 1].mean() < 0.05  # the check works


@pytest.mark.parametrize("cls", [TriangulationEstimator, FittedTriangulationEstimator])
def test_a_frame_without_contact_gets_its_own_writeable_row(cls: type[TriangulationEstimator]) -> None:
    """Frames without contact get a new row of zeros each, writeable as every other result: a caller
    that writes into one result changes no other (estimator contract: outputs never alias state)."""
    est = cls(SCENE).prepare()
    frames = np.ascontiguousarray(fsr.make_simulator(SCENE).simulate(200, np.random.default_rng(94))["readings"])
    frames = frames.astype(np.float32)
    batch = est.predict(frames)
    idle = np.flatnonzero(batch[:, 3] == 0)
    assert len(idle) > 10 and (batch[:, 3] > 0).sum() > 10
    frame = frames[idle[0] : idle[0] + 1]
    for call in (est.predict, FrameStream(est).predict, est.frame_runner()):
        first = call(frame)
        assert first.dtype == np.float32 and first.shape == (1, 6) and first.flags.writeable
        first[0, :] = 7.0  # the caller's own array
        np.testing.assert_array_equal(call(frame), np.zeros((1, 6), dtype=np.float32))


def test_a_gate_below_float64s_range_is_zero_on_both_paths() -> None:
    """A film whose break lies far above its width (more than 709 widths): light loads put the
    gate's exponent beyond float64, where the batch path's logistic gives exactly 0 (the
    conductance is the leak alone); the one-frame model and its normal equations give the same."""
    from tactile_learn.fsr_check import OnePressCheck

    element = dataclasses.replace(SCENE.sensor.element, break_force_n=0.3, break_width_n=2e-4)
    scene = dataclasses.replace(SCENE, sensor=dataclasses.replace(SCENE.sensor, element=element))
    batch = OnePressCheck(scene).prepare()
    one = batch.one_frame
    assert one.break_n / one.width_n > 710.0
    rng = np.random.default_rng(95)
    params = np.column_stack([rng.uniform(-30.0, 30.0, (300, 2)), rng.uniform(-3.0, 3.0, 300)])
    want = batch.conductance(params)
    got = np.array([one.conductance(x, y, log_force) for x, y, log_force in params.tolist()])
    gated_off = want == one.leak
    assert gated_off.sum() > 100 and (~gated_off).sum() > 100
    np.testing.assert_array_equal(got[gated_off], one.leak)  # exactly the leak where the batch's gate is 0
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=0.0)  # (tanh: libm's against numpy's)
    for (x, y, log_force), row in zip(params.tolist()[:50], got[:50].tolist(), strict=True):
        model, _ = one.model_and_normal_equations(x, y, log_force, one.column(log_force), row)
        assert model == row
