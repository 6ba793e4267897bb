"""OnnxEstimator.predict checks one frame on its one-frame path (tactile_learn.onnx_one_frame):
the same results as the full check, the same clear errors for bad frames, and no fast path where
the scene's check maps readings (a calibrated film)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from synth.errors import InputError
from synth.sensors import fsr
from tactile_learn.methods import shipped_models
from tactile_learn.runtime import OnnxEstimator


@pytest.fixture(scope="module")
def fsr_model() -> OnnxEstimator:
    return OnnxEstimator(shipped_models("fsr")["fsr"], threads=1).prepare()


def test_single_frames_equal_the_fully_checked_path(fsr_model: OnnxEstimator) -> None:
    assert fsr_model.one_frame_ is not None
    scene = fsr_model.card_scene_
    frames = np.ascontiguousarray(fsr.make_simulator(scene).simulate(200, np.random.default_rng(41))["readings"])
    frames = frames.astype(np.float32)
    fast = np.concatenate([fsr_model.predict(frames[i : i + 1]) for i in range(len(frames))])
    full = np.concatenate(
        [fsr_model.predict_checked(fsr_model.input_check_(frames[i : i + 1])) for i in range(len(frames))]
    )
    np.testing.assert_array_equal(fast, full)
    assert (fast[:, 3] > 0.5).any() and (fast[:, 3] < 0.5).any()


@pytest.mark.parametrize(
    ("value", "message"), [(np.nan, "NaN or inf"), (np.inf, "NaN or inf"), (-1.0, "negative"), (1023.0, "saturated")]
)
def test_bad_single_frames_get_the_clear_error(fsr_model: OnnxEstimator, value: float, message: str) -> None:
    frame = np.full((1, 6), 200.0, dtype=np.float32)
    frame[0, 4] = value
    with pytest.raises(InputError, match=message):
        fsr_model.predict(frame)


def test_no_fast_check_where_the_check_maps_readings(fsr_model: OnnxEstimator) -> None:
    card_scene = fsr_model.card_scene_
    film = dataclasses.replace(card_scene.sensor.film, gains=(1.05, 0.95, 1.02, 0.97, 1.04, 0.96), gain_spread=0.0)
    scene = dataclasses.replace(card_scene, sensor=dataclasses.replace(card_scene.sensor, film=film))
    calibrated = OnnxEstimator(fsr_model.path, threads=1, scene=scene).prepare()
    assert calibrated.one_frame_ is None
    frame = np.array([[300.0, 280.0, 120.0, 40.0, 20.0, 0.0]], dtype=np.float32)
    # the calibrated film's readings are mapped to the nominal film's before the network
    assert not np.array_equal(calibrated.predict(frame), fsr_model.predict(frame))


def test_strip_frames_take_the_one_frame_path_too() -> None:
    strips = OnnxEstimator(shipped_models("strips")["strips16"], threads=1).prepare()
    assert strips.one_frame_ is not None  # 32 readings: one reduction over their bit patterns
    frame = np.full((1, 32), 0.2, dtype=np.float32)
    np.testing.assert_array_equal(strips.predict(frame), strips.predict_checked(strips.input_check_(frame)))
