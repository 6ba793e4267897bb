"""A thermal training stream that simulates only the pixels training reads."""

from __future__ import annotations

import numpy as np
import pytest

from synth.errors import ConfigError
from synth.scene import load_scene
from tactile_learn.stream import TouchStream
from tactile_learn.tasks import get_task


def test_a_pixel_stream_feeds_training_batches_of_the_pixels_it_simulated() -> None:
    scene = load_scene("thermal_wns")
    stream = TouchStream(scene, 40, 5, shard_size=16, pixels=4)
    arrays = stream.arrays()
    assert arrays["readings"].shape[:2] == (40, 4)
    assert stream.describe()["pixels_per_touch"] == 4
    task = get_task("thermal")
    x, targets = task.training_batch(arrays, scene, np.random.default_rng(0))
    assert len(x) == len(targets["label"]) == 40 * 4  # every simulated pixel is trained on
    assert np.isfinite(x).all()


def test_a_pixel_stream_refuses_a_count_the_array_does_not_have_before_simulating() -> None:
    with pytest.raises(ConfigError, match="pixels"):
        TouchStream(load_scene("thermal"), 10, 1, pixels=32)


def test_stream_pixels_need_a_stream() -> None:
    pytest.importorskip("torch", reason="torch (training extra) is not installed")
    from tactile_learn.train import TrainConfig

    with pytest.raises(ConfigError, match="stream-pixels"):
        TrainConfig(task="thermal", data="data/d", val="data/v", out="runs/o", stream_pixels=4).validate()
