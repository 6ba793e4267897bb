"""Single-frame paths of the classical methods (batch 1, the streaming case) against their batch
paths: the same results frame by frame, the same errors for bad input."""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np
import pytest

from synth.errors import InputError
from synth.scene import Scene, load_scene, parse_scene
from synth.sensors import sensor_module
from tactile_learn.bench import _bench_data
from tactile_learn.estimators.base import Estimator
from tactile_learn.frame_stream import FrameStream
from tactile_learn.tasks import get_task
from tactile_learn.thermal_frame import detect_onset_one, drop_segment_one
from tactile_learn.thermal_signal import detect_onset, drop_segments
from tests.conftest import tiny_strips_scene

SCENES = {"strips": "strips16", "capacitive": "capacitive8", "thermal": "thermal"}


@cache
def held_out(task_name: str, n: int) -> np.ndarray:
    """Inputs of ``n`` samples of the task's default scene (the benchmark's held-out seed)."""
    task = get_task(task_name)
    return np.ascontiguousarray(task.latency_inputs(_bench_data(task_name, None, n, None)), dtype=np.float32)


def method(task_name: str, name: str, scene: Scene | None = None) -> Estimator:
    scene = scene or load_scene(SCENES[task_name])
    return get_task(task_name).classical_methods()[name](scene)


def one_by_one(est: Estimator, frames: np.ndarray) -> np.ndarray:
    call = est.predict_proba if est.is_classifier else est.predict
    return np.concatenate([call(frames[i : i + 1]) for i in range(len(frames))])


def batch(est: Estimator, frames: np.ndarray) -> np.ndarray:
    return est.predict_proba(frames) if est.is_classifier else est.predict(frames)


def relative_error(single: np.ndarray, whole: np.ndarray) -> np.ndarray:
    """Per frame: the largest difference over the frame's largest value."""
    diff = np.abs(single.astype(np.float64) - whole).reshape(len(whole), -1).max(axis=1)
    return diff / np.maximum(np.abs(whole).reshape(len(whole), -1).max(axis=1), 1e-30)


def test_intersection_single_frames_equal_the_batch() -> None:
    frames = held_out("strips", 150)
    est = method("strips", "intersection")
    assert est.frame_loads_ is not None  # the orthogonal pair takes the single-frame path
    whole = batch(est, frames)
    assert (whole.reshape(len(whole), -1).max(axis=1) > 0).mean() > 0.5  # mostly touched frames
    np.testing.assert_allclose(one_by_one(est, frames), whole, rtol=1e-6, atol=1e-6)


def test_intersection_other_layouts_go_through_the_batch_path() -> None:
    data = load_scene("strips16").to_dict()
    data["strips"]["geometry"]["layout"] = "two_ended"
    scene = parse_scene(data, "two_ended")
    est = method("strips", "intersection", scene)
    assert est.frame_loads_ is None  # its readouts are not all dividers
    readings = sensor_module("strips").make_simulator(scene).simulate(20, np.random.default_rng(3))["readings"]
    readings = readings.astype(np.float32)
    np.testing.assert_array_equal(one_by_one(est, readings), batch(est, readings))


def test_projection_single_frames_equal_the_batch_within_float32_rounding() -> None:
    frames = held_out("strips", 60)
    est = method("strips", "projection")
    whole = batch(est, frames)
    single = one_by_one(est, frames)
    # float32 sums in another order: a frame may stop one iteration earlier or later, whose change
    # is below rel_tol (1e-4) of the map
    assert relative_error(single, whole).max() < 2e-4
    assert np.median(relative_error(single, whole)) < 2e-5
    # cells the start leaves dark stay dark on both paths
    np.testing.assert_array_equal(single > 0, whole > 0)


@pytest.mark.parametrize("layout", ["two_ended", "diagonal"])
def test_projection_single_frames_of_other_layouts_equal_the_batch(layout: str) -> None:
    data = tiny_strips_scene(count=[1, 2]).to_dict()
    data["strips"]["geometry"]["layout"] = layout
    scene = parse_scene(data, layout)
    est = method("strips", "projection", scene)
    readings = sensor_module("strips").make_simulator(scene).simulate(30, np.random.default_rng(4))["readings"]
    readings = np.ascontiguousarray(readings, dtype=np.float32)
    readings = readings[readings.max(axis=1) < scene.sensor.readout.full_scale_v]  # saturated frames are refused
    whole = batch(est, readings)
    assert len(readings) > 20 and (whole.reshape(len(whole), -1).max(axis=1) > 0).mean() > 0.5
    assert relative_error(one_by_one(est, readings), whole).max() < 2e-4


def test_projection_single_idle_frame_is_zero() -> None:
    scene = load_scene("strips16")
    est = method("strips", "projection", scene)
    idle = np.full((1, 32), scene.sensor.readout.offset_v, dtype=np.float32)  # every strip at rest
    out = est.predict(idle)
    assert out.shape == (1, 16, 16) and not out.any()


@pytest.mark.parametrize("name", ["bicubic", "deconvolution"])
def test_capacitive_single_frames_equal_the_batch(name: str) -> None:
    frames = held_out("capacitive", 12 if name == "deconvolution" else 40)
    est = method("capacitive", name)
    whole = batch(est, frames)
    single = one_by_one(est, frames)
    assert whole[:, 1].any(axis=(1, 2)).mean() > 0.3  # frames with a contact mask
    assert (~whole[:, 1].any(axis=(1, 2))).any()  # and frames without
    assert relative_error(single[:, 0], whole[:, 0]).max() < 1e-5
    # a mask pixel may only flip where its force sits on the threshold (float32 rounding)
    assert np.mean(single[:, 1] != whole[:, 1]) < 1e-4


def test_curve_match_single_curves_equal_the_batch() -> None:
    curves = held_out("thermal", 30)
    est = method("thermal", "curve_match")
    whole = batch(est, curves)
    single = one_by_one(est, curves)
    assert (whole[:, -1] < 0.5).mean() > 0.3  # touches classified as materials, not just "none"
    np.testing.assert_allclose(single, whole, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(single.argmax(axis=1), whole.argmax(axis=1))


def thermal_variants(curves: np.ndarray, rng: np.random.Generator) -> list[np.ndarray]:
    """The curves as recorded, padded at the start (a window reaching before its record) and
    noise-free (quantised to 0.1 degC: the padded run may be a true baseline)."""
    padded = curves.astype(np.float64)
    for row, k in zip(padded, rng.integers(0, 60, len(padded)), strict=True):
        row[:k] = row[k]
    return [curves.astype(np.float64), padded, np.round(curves.astype(np.float64), 1)]


def test_single_curve_onsets_equal_the_batch_bit_for_bit() -> None:
    config = load_scene("thermal").sensor
    fs, step = config.readout.sampling_hz, config.readout.adc_step_k
    for x in thermal_variants(held_out("thermal", 20), np.random.default_rng(7)):
        onset = detect_onset(x, fs, step)
        drops, n_valid = drop_segments(x, onset)
        assert 0.2 < onset.detected.mean() < 1.0
        for i, curve in enumerate(x):
            one = detect_onset_one(curve, fs, step)
            assert (one.index, one.detected, one.baseline, one.sigma, one.direction) == (
                onset.index[i],
                onset.detected[i],
                onset.baseline[i],
                onset.sigma[i],
                onset.direction[i],
            )
            y, valid = drop_segment_one(curve, one)
            assert valid == n_valid[i]
            np.testing.assert_array_equal(y, drops[i])


BAD_FRAMES: list[tuple[str, str, Any, str]] = [
    ("strips", "intersection", "nan", "NaN"),
    ("strips", "projection", "negative", "negative"),
    ("strips", "intersection", "shape", "expected shape"),
    ("capacitive", "bicubic", "nan", "NaN"),
    ("capacitive", "bicubic", "shape", "expected shape"),
    ("thermal", "curve_match", "inf", "NaN or inf"),
    ("thermal", "curve_match", "shape", "expected shape"),
]


@pytest.mark.parametrize(("task_name", "name", "kind", "message"), BAD_FRAMES)
def test_bad_single_frames_raise_clear_errors(task_name: str, name: str, kind: str, message: str) -> None:
    frame = held_out(task_name, 4)[:1].copy()
    if kind == "nan":
        frame.flat[1] = np.nan
    elif kind == "inf":
        frame.flat[1] = np.inf
    elif kind == "negative":
        frame.flat[1] = -0.5
    else:
        frame = frame[0]  # no batch axis
    est = method(task_name, name)
    for call in (est.predict, FrameStream(est).predict):
        with pytest.raises(InputError, match=message):
            call(frame)


@pytest.mark.parametrize(("task_name", "name"), [("strips", "intersection"), ("capacitive", "bicubic")])
def test_stream_of_single_frames_equals_predict(task_name: str, name: str) -> None:
    frames = held_out(task_name, 30)
    est = method(task_name, name)
    stream = FrameStream(est)
    streamed = np.concatenate([stream.predict(frames[i : i + 1]) for i in range(len(frames))])
    np.testing.assert_array_equal(streamed, one_by_one(est, frames))
