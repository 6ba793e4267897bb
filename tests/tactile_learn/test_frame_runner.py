"""A learned model's single frames through the stream's io binding
(:meth:`tactile_learn.runtime.OnnxEstimator.frame_runner`): the same results as ``predict``."""

from __future__ import annotations

import numpy as np
import pytest

from synth.errors import InputError
from tactile_learn.bench import _bench_data
from tactile_learn.frame_stream import FrameStream
from tactile_learn.methods import shipped_models
from tactile_learn.runtime import OnnxEstimator

MODELS = sorted((task, name) for task in ("strips", "fsr", "thermal", "capacitive") for name in shipped_models(task))


@pytest.mark.parametrize(("task_name", "name"), MODELS)
def test_stream_single_frames_equal_predict(task_name: str, name: str) -> None:
    from tactile_learn.tasks import get_task

    model = OnnxEstimator(shipped_models(task_name)[name], threads=1).prepare()
    task = get_task(task_name)
    frames = task.latency_inputs(_bench_data(task_name, model.card_scene_, 6, None))
    frames = np.ascontiguousarray(frames[:12], dtype=np.float32)
    stream = FrameStream(model)
    assert stream._compute_one is not None  # every shipped graph has a float32 output of fixed shape
    streamed = [stream.predict(frames[i : i + 1]) for i in range(len(frames))]
    direct = model.predict_proba if model.is_classifier else model.predict
    expected = [direct(frames[i : i + 1]) for i in range(len(frames))]
    for got, want in zip(streamed, expected, strict=True):
        np.testing.assert_array_equal(got, want)  # earlier results are not overwritten by later frames
    assert not np.shares_memory(streamed[0], streamed[1])
    with pytest.raises(InputError, match="NaN"):
        bad = frames[:1].copy()
        bad.flat[0] = np.nan
        stream.predict(bad)
