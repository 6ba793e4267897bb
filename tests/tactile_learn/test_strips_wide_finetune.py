"""``train --init`` without ``--size`` keeps the size of the weights it starts from (a widened
network, made by scripts/strips_grow.py, fine-tunes through the CLI; an explicit other size is
refused, naming the file)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed")

from synth.dataset import generate
from synth.scene import load_scene
from tactile_learn.checkpoints import load_weights
from tactile_learn.cli import main


def test_a_fine_tune_keeps_the_size_of_its_init(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    generate(load_scene("strips16_mixed"), 60, 2, tmp_path / "train", shard_size=30)
    generate(load_scene("strips16_mixed"), 30, 3, tmp_path / "val")
    init = "models/strips16.pt"
    size = load_weights(init)["size"]
    other = "tiny" if size != "tiny" else "small"
    argv = ["train", "--task", "strips", "--data", str(tmp_path / "train"), "--val", str(tmp_path / "val")]
    argv += ["--epochs", "1", "--batch-size", "30", "--threads", "1", "--quiet", "--val-limit", "30", "--init", init]
    assert main([*argv, "--out", str(tmp_path / "tuned")]) == 0
    metrics = json.loads((tmp_path / "tuned" / "metrics.json").read_text())
    tuned = load_weights(tmp_path / "tuned")
    assert metrics["size"] == size and tuned["size"] == size
    assert tuned["state_dict"]["head.weight"].shape == load_weights(init)["state_dict"]["head.weight"].shape
    assert main([*argv, "--out", str(tmp_path / "other"), "--size", other]) != 0
    assert f"holds a {size!r} network, not {other!r}" in capsys.readouterr().err
