"""``train --r-weight``: the weight of the strip loss's per-frame (1 - Pearson r) term."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed")

import torch

from synth.dataset import generate
from synth.errors import ConfigError
from synth.scene import load_scene
from tactile_learn.cli import main
from tactile_learn.nets.strips import strip_loss
from tactile_learn.train import TrainConfig


def _maps() -> tuple[torch.Tensor, torch.Tensor]:
    gen = torch.Generator().manual_seed(0)
    target = torch.rand(8, 5, 5, generator=gen)
    # the same maps, each frame rescaled and shifted: r = 1 everywhere, the MSE is not zero
    pred = target * torch.linspace(0.5, 2.0, 8)[:, None, None] + 0.1
    return pred, target


def test_the_r_term_is_weighed_and_only_the_r_term() -> None:
    pred, target = _maps()
    mse = strip_loss(pred, target, r_weight=0.0)
    assert float(mse) > 0.0
    assert float(strip_loss(pred, target, r_weight=5.0)) == pytest.approx(float(mse), abs=1e-6)  # r = 1: no r term
    noisy = pred + 0.3 * torch.rand(pred.shape, generator=torch.Generator().manual_seed(1))
    base, one, three = (float(strip_loss(noisy, target, r_weight=w)) for w in (0.0, 1.0, 3.0))
    assert one > base and three - base == pytest.approx(3.0 * (one - base), rel=1e-5)
    assert one == pytest.approx(float(strip_loss(noisy, target)), rel=1e-7)  # 1: the default loss


def test_out_of_range_and_unsupported_weights_are_refused() -> None:
    with pytest.raises(ConfigError, match="--r-weight"):
        TrainConfig(task="strips", data="d", out="o", r_weight=-1.0).validate()
    with pytest.raises(ConfigError, match="no per-frame r term"):
        TrainConfig(task="fsr", data="d", out="o", r_weight=2.0).validate()
    assert TrainConfig(task="fsr", data="d", out="o").loss_options() == {}  # every task's loss at the default
    assert TrainConfig(task="strips", data="d", out="o", r_weight=3.0).loss_options() == {"r_weight": 3.0}


def test_train_records_the_weight_and_trains_differently(tmp_path: Path) -> None:
    generate(load_scene("strips16_mixed"), 100, 2, tmp_path / "train", shard_size=50)
    generate(load_scene("strips16_mixed"), 50, 3, tmp_path / "val")
    argv = ["train", "--task", "strips", "--data", str(tmp_path / "train"), "--val", str(tmp_path / "val")]
    argv += ["--epochs", "1", "--batch-size", "25", "--threads", "1", "--quiet", "--size", "tiny", "--val-limit", "50"]
    losses = {}
    for w in ("1", "4"):
        assert main([*argv, "--out", str(tmp_path / f"r{w}"), "--r-weight", w]) == 0
        metrics = json.loads((tmp_path / f"r{w}" / "metrics.json").read_text())
        assert metrics["config"]["r_weight"] == float(w)
        losses[w] = metrics["history"][0]["train_loss"]
    assert losses["4"] > losses["1"]  # the same batches, the r term counted four times
