"""The frame stream's one-frame check and gate (tactile_learn.stream_one_frame) make the decisions of
the numpy path: the same idle frames skipped, the same results, the same errors for bad frames."""

from __future__ import annotations

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.errors import InputError
from tactile_learn.frame_stream import FrameStream
from tactile_learn.idle import idle_scene
from tactile_learn.methods import shipped_models
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.stream_one_frame import OneFrameGate
from tactile_learn.tasks import get_task


@pytest.fixture(scope="module")
def fsr_model() -> OnnxEstimator:
    return OnnxEstimator(shipped_models("fsr")["fsr"], threads=1).prepare()


def _mixed_frames(model: OnnxEstimator) -> np.ndarray:
    scene = model.card_scene_
    task = get_task("fsr")
    rest = idle_scene(scene)
    idle = task.example_inputs(simulate_shard(rest, 8080, 0, 150), rest)
    busy = task.example_inputs(simulate_shard(scene, 8080, 1, 150), scene)
    return np.ascontiguousarray(np.concatenate([idle, busy]), dtype=np.float32)


def test_one_frame_at_a_time_equals_the_batch_path(fsr_model: OnnxEstimator) -> None:
    frames = _mixed_frames(fsr_model)
    for gate in (False, True):
        one, numpy_path = FrameStream(fsr_model, gate=gate), FrameStream(fsr_model, gate=gate)
        assert one._one_frame is not None
        singles = np.concatenate([one.predict(frames[i : i + 1]) for i in range(len(frames))])
        # float64 frames take the numpy check and gate (the network still sees one frame at a time)
        numpy_singles = [numpy_path.predict(frames[i : i + 1].astype(np.float64)) for i in range(len(frames))]
        np.testing.assert_array_equal(singles, np.concatenate(numpy_singles))
        assert (one.frames, one.skipped) == (numpy_path.frames, numpy_path.skipped)
        batch = FrameStream(fsr_model, gate=gate)
        np.testing.assert_allclose(singles, batch.predict(frames), rtol=1e-5, atol=1e-5)  # the network's rounding
        assert batch.skipped == one.skipped
        if gate:
            assert 0.3 < one.skipped_share < 0.9  # both kinds of frame were there


def test_frames_at_the_threshold_are_gated_as_the_numpy_gate_does(fsr_model: OnnxEstimator) -> None:
    stream = FrameStream(fsr_model, gate=True)
    gate, one = stream.gate, stream._one_frame
    assert gate is not None and one is not None
    # one value swept across the threshold, a float32 step at a time around it
    edge = np.float32(gate.mean[2] + gate.threshold / gate.inv_sd[2])
    steps = [edge]
    for _ in range(40):
        steps.insert(0, np.nextafter(steps[0], np.float32(-np.inf)))
        steps.append(np.nextafter(steps[-1], np.float32(np.inf)))
    verdicts = []
    for value in steps:
        frame = gate.mean[None].copy()
        frame[0, 2] = value
        verdicts.append(one.verdict(frame))
        assert verdicts[-1] == bool(gate.active(frame)[0])
    assert {True, False} == set(verdicts)


@pytest.mark.parametrize(("value", "message"), [(np.nan, "NaN or inf"), (-3.0, "negative"), (1023.0, "saturated")])
def test_a_bad_single_frame_still_gets_the_clear_error(fsr_model: OnnxEstimator, value: float, message: str) -> None:
    stream = FrameStream(fsr_model, gate=True)
    frame = _mixed_frames(fsr_model)[:1].copy()
    frame[0, 4] = value
    with pytest.raises(InputError, match=message):
        stream.predict(frame)
    assert stream.frames == 0


def test_large_frames_and_mapped_inputs_keep_the_numpy_path() -> None:
    assert OneFrameGate.build((32,), (0.0, 5.0, False), None) is None  # a strip frame: 32 values
    assert OneFrameGate.build((6,), None, None) is None  # a calibrated film: its check maps readings
    assert OneFrameGate.build((6,), (0.0, 1023.0, False), None) is not None
