"""The batch-1 path of OnnxEstimator.predict (tactile_learn.onnx_one_frame): the range check on bit
patterns refuses exactly what the full check refuses (or leaves a frame to it), single frames give
the fully checked path's results bit for bit and the batch path's to float32 rounding, bad frames
the same clear errors, and a busy path hands over to the ordinary one."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from synth.errors import InputError
from tactile_learn.bench import _bench_data
from tactile_learn.methods import shipped_models
from tactile_learn.onnx_one_frame import OneFrameRun, below_bits
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.tasks import get_task

MODELS = sorted((task, name) for task in ("strips", "fsr", "thermal", "capacitive") for name in shipped_models(task))


def _model(task_name: str, name: str) -> OnnxEstimator:
    return OnnxEstimator(shipped_models(task_name)[name], threads=1).prepare()


def _frames(model: OnnxEstimator, n: int = 24) -> np.ndarray:
    task = get_task(model.task_name)
    frames = task.latency_inputs(_bench_data(model.task_name, model.card_scene_, 12, None))
    return np.ascontiguousarray(frames[:n], dtype=np.float32)


@pytest.mark.parametrize("high", [3.3, 1023.0, 1.0, 5.0, 1e-3, 4095.5])
def test_below_bits_splits_the_float32_values_at_high(high: float) -> None:
    last, first = np.array([below_bits(high) - 1, below_bits(high)], dtype=np.uint32).view(np.float32)
    assert float(last) < high <= float(first)  # compared in double, as the full check compares


@pytest.mark.parametrize(("task_name", "name"), MODELS)
def test_single_frames_equal_the_checked_path_and_the_batch(task_name: str, name: str) -> None:
    model = _model(task_name, name)
    frames = _frames(model)
    singles = [model.predict(frames[i : i + 1]) for i in range(len(frames))]
    if model.one_frame_ is not None:
        assert not np.shares_memory(singles[0], singles[1])  # each result is the caller's
    checked = [model.predict_checked(model.input_check_(frames[i : i + 1])) for i in range(len(frames))]
    for got, want in zip(singles, checked, strict=True):
        np.testing.assert_array_equal(got, want)
    batch = model.predict(frames)
    if model.is_classifier:
        np.testing.assert_array_equal(np.concatenate(singles), batch)
        probabilities = np.concatenate([model.predict_proba(frames[i : i + 1]) for i in range(len(frames))])
        np.testing.assert_allclose(probabilities, model.predict_proba(frames), rtol=1e-5, atol=1e-6)
    else:  # onnxruntime's batch kernels may round differently from its one-row kernels
        scale = float(np.abs(batch).max()) or 1.0
        np.testing.assert_allclose(np.concatenate(singles), batch, rtol=1e-4, atol=1e-5 * scale)


@pytest.mark.parametrize(("task_name", "name"), [("fsr", "fsr"), ("strips", "strips16_small")])
@pytest.mark.parametrize(
    ("value", "message"),
    [(np.nan, "NaN or inf"), (np.inf, "NaN or inf"), (-np.inf, "NaN or inf"), (-1e-30, "negative"), (-2.0, "negative")],
)
def test_bad_frames_get_the_full_checks_error(task_name: str, name: str, value: float, message: str) -> None:
    model = _model(task_name, name)
    frame = _frames(model, 1).copy()
    frame[0, 3] = value
    assert model.one_frame_ is not None and model.one_frame_(frame) is None  # left to the full check
    with pytest.raises(InputError, match=message):
        model.predict(frame)


@pytest.mark.parametrize(("task_name", "name"), [("fsr", "fsr"), ("strips", "strips16_small")])
def test_the_range_ends_as_the_full_check_has_them(task_name: str, name: str) -> None:
    model = _model(task_name, name)
    one = model.one_frame_
    assert one is not None
    high = model.input_check_.upper
    assert high is not None
    frame = _frames(model, 1).copy()
    frame[0, 1] = np.float32(high)  # saturated: refused
    if float(frame[0, 1]) >= high:
        assert one(frame) is None
        with pytest.raises(InputError, match="saturated"):
            model.predict(frame)
    frame[0, 1] = np.array(below_bits(high) - 1, dtype=np.uint32).view(np.float32)  # the top valid value
    frame[0, 2] = 0.0  # the bottom one
    assert one(frame) is not None
    np.testing.assert_array_equal(model.predict(frame), model.predict_checked(model.input_check_(frame)))
    frame[0, 2] = -0.0  # valid for the full check, refused by the bit check: the full path answers
    assert one(frame) is None
    np.testing.assert_array_equal(model.predict(frame), model.predict_checked(model.input_check_(frame)))


def test_other_inputs_take_the_ordinary_path() -> None:
    model = _model("strips", "strips16_small")
    frames = _frames(model, 4)
    want = model.predict(frames[:1])
    one = model.one_frame_
    assert one is not None
    wide = np.asfortranarray(np.repeat(frames[:1], 2, axis=0))[:1]
    for other in (frames[:1].astype(np.float64), frames[:1].tolist(), frames[:1].astype(">f4")):
        assert one(other) is None
        np.testing.assert_array_equal(model.predict(other), want)
    np.testing.assert_array_equal(model.predict(wide), want)  # a strided view: copied into the buffer
    np.testing.assert_array_equal(model.predict(frames[:2])[:1], model.predict_checked(frames[:2])[:1])
    with pytest.raises(InputError, match="shape"):
        model.predict(frames[0])


def test_a_busy_path_hands_over_to_the_ordinary_one() -> None:
    model = _model("fsr", "fsr")
    frames = _frames(model, 8)
    one = model.one_frame_
    assert one is not None
    want = [model.predict(frames[i : i + 1]) for i in range(len(frames))]
    with one._lock:  # another thread's frame in flight
        assert one(frames[:1]) is None
        got = [model.predict(frames[i : i + 1]) for i in range(len(frames))]
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)
    results: dict[int, list[np.ndarray]] = {}

    def worker(k: int) -> None:
        results[k] = [model.predict(frames[i : i + 1]) for i in range(len(frames)) for _ in range(20)]

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(3)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for k in range(3):
        for j, result in enumerate(results[k]):
            np.testing.assert_array_equal(result, want[j // 20])


def test_a_range_with_a_lower_bound_uses_two_reductions() -> None:
    model = _model("fsr", "fsr")
    _, output, input_name = model.run_
    run = OneFrameRun(model.session_, input_name, output[0], (6,), (5,), (100.0, 1023.0, True), model.finish_)
    frame = np.full((1, 6), 300.0, dtype=np.float32)
    assert run(frame) is not None
    for value in (100.0, 50.0, np.nan, 1023.0):
        frame[0, 5] = value
        assert run(frame) is None
    frame[0, 5] = np.nextafter(np.float32(100.0), np.float32(200.0))
    np.testing.assert_array_equal(run(frame), model.predict(frame))


def test_an_ungated_stream_has_its_own_one_frame_run() -> None:
    from tactile_learn.frame_stream import FrameStream

    model = _model("fsr", "fsr")
    frames = _frames(model, 6)
    stream = FrameStream(model)
    assert stream._run_one is not None and stream._run_one is not model.one_frame_
    got = [stream.predict(frames[i : i + 1]) for i in range(len(frames))]
    for i, result in enumerate(got):
        np.testing.assert_array_equal(result, model.predict(frames[i : i + 1]))
    assert stream.frames == len(frames)
    assert FrameStream(model, gate=True)._run_one is None  # a gated stream gates first
