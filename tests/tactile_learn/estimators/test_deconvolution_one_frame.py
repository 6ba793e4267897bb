"""The deconvolution's single-frame path (tactile_learn.estimators.classical.deconvolution_one_frame)
against its batch path: the same images to float32 rounding on many frames, as close to a float64
run as the batch path is, the same errors for bad frames."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from synth.errors import InputError
from synth.scene import load_scene
from tactile_learn.bench import _bench_data
from tactile_learn.estimators.classical.capacitive import DeconvolutionEstimator, _laplacian
from tactile_learn.estimators.classical.deconvolution_one_frame import momentum_weights, neumann_laplacian
from tactile_learn.frame_stream import FrameStream
from tactile_learn.tasks import get_task


@cache
def frames(n: int) -> np.ndarray:
    """Calibrated cell loads of ``n`` held-out capacitive8 presses (the benchmark's frames)."""
    task = get_task("capacitive")
    return np.ascontiguousarray(task.latency_inputs(_bench_data("capacitive", None, n, None)), dtype=np.float32)


@cache
def estimator() -> DeconvolutionEstimator:
    return DeconvolutionEstimator(load_scene("capacitive8")).prepare()


def per_frame_error(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per frame: the largest difference over the reference's largest value."""
    diff = np.abs(image.astype(np.float64) - reference).reshape(len(reference), -1).max(axis=1)
    return diff / np.maximum(np.abs(reference).reshape(len(reference), -1).max(axis=1), 1e-30)


def test_kronecker_sum_of_the_1d_laplacians_is_the_batch_laplacian() -> None:
    image = np.random.default_rng(5).standard_normal((3, 7, 5))
    folded = neumann_laplacian(7) @ image + image @ neumann_laplacian(5)
    np.testing.assert_allclose(folded, _laplacian(image), rtol=0, atol=1e-12)


def test_momentum_weights_are_fistas() -> None:
    weights = momentum_weights(4)
    t = [1.0, (1 + 5**0.5) / 2]
    t.append((1 + (1 + 4 * t[1] ** 2) ** 0.5) / 2)
    assert weights[0] == 0.0
    assert weights[1] == np.float32((t[1] - 1) / t[2])


def test_single_frames_equal_the_batch_path_on_many_frames() -> None:
    loads = frames(80)[::3]  # 8 frames a press: 214 frames of 80 presses
    est = estimator()
    whole = est.predict(loads)
    single = np.concatenate([est.predict(loads[i : i + 1]) for i in range(len(loads))])
    touched = whole[:, 1].any(axis=(1, 2))
    assert touched.mean() > 0.3 and (~touched).any()  # frames with a contact mask and without
    assert per_frame_error(single[:, 0], whole[:, 0]).max() < 2e-5
    # a mask pixel may only flip where its force sits on the threshold (float32 rounding)
    assert np.mean(single[:, 1] != whole[:, 1]) < 1e-4


def test_single_frames_are_as_close_to_float64_as_the_batch_path() -> None:
    loads = frames(40)[::5]
    est = estimator()
    config = est.scene.sensor
    reference = est._force(loads.astype(np.float64), config)  # the batch path's arithmetic in float64
    assert reference.dtype == np.float64
    batch_error = per_frame_error(est._force(loads, config), reference)
    single_error = per_frame_error(np.stack([est.single_force(frame, est.upsampler_) for frame in loads]), reference)
    assert batch_error.max() < 1e-4  # float32 rounding, not another algorithm
    assert single_error.max() <= 2.0 * batch_error.max() + 1e-7


def test_more_iterations_change_the_single_frame_path_as_the_batch() -> None:
    scene = load_scene("capacitive8")
    loads = frames(8)[:6:2]
    short, long = (DeconvolutionEstimator(scene, iterations=n).prepare() for n in (5, 30))
    for est in (short, long):
        single = np.concatenate([est.predict(loads[i : i + 1]) for i in range(len(loads))])
        assert per_frame_error(single[:, 0], est.predict(loads)[:, 0]).max() < 2e-5
    assert per_frame_error(short.predict(loads[:1])[:, 0], long.predict(loads[:1])[:, 0]).max() > 1e-3


@pytest.mark.parametrize(
    ("kind", "message"), [("nan", "NaN"), ("inf", "NaN or inf"), ("negative", "negative"), ("shape", "shape")]
)
def test_bad_single_frames_are_refused(kind: str, message: str) -> None:
    frame = frames(4)[:1].copy()
    if kind == "nan":
        frame[0, 2, 3] = np.nan
    elif kind == "inf":
        frame[0, 2, 3] = np.inf
    elif kind == "negative":
        frame[0, 2, 3] = -5.0
    else:
        frame = frame[:, :7]
    est = estimator()
    for call in (est.predict, FrameStream(est).predict):
        with pytest.raises(InputError, match=message):
            call(frame)


def test_stream_of_single_frames_equals_predict() -> None:
    loads = frames(12)[::4]
    est = estimator()
    stream = FrameStream(est)
    streamed = np.concatenate([stream.predict(loads[i : i + 1]) for i in range(len(loads))])
    np.testing.assert_array_equal(streamed, np.concatenate([est.predict(loads[i : i + 1]) for i in range(len(loads))]))
