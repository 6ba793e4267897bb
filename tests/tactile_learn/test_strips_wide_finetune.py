"""Fine-tuning a widened general strip network: ``train --init`` without ``--size`` keeps the size
of the weights it starts from (the wide size is reached by scripts/strips_grow.py, not by --size)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed")

from synth.dataset import generate
from synth.scene import load_scene
from tactile_learn.checkpoints import load_weights
from tactile_learn.cli import main

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
import strips_grow


def test_a_fine_tune_keeps_the_size_of_its_init(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    generate(load_scene("strips16_mixed"), 60, 2, tmp_path / "train", shard_size=30)
    generate(load_scene("strips16_mixed"), 30, 3, tmp_path / "val")
    assert strips_grow.main(["models/strips16.pt", "--size", "wide", "--out", str(tmp_path / "wide.pt")]) == 0
    argv = ["train", "--task", "strips", "--data", str(tmp_path / "train"), "--val", str(tmp_path / "val")]
    argv += ["--epochs", "1", "--batch-size", "30", "--threads", "1", "--quiet", "--val-limit", "30"]
    argv += ["--init", str(tmp_path / "wide.pt")]
    assert main([*argv, "--out", str(tmp_path / "tuned")]) == 0
    metrics = json.loads((tmp_path / "tuned" / "metrics.json").read_text())
    assert metrics["size"] == "wide"
    tuned = load_weights(tmp_path / "tuned")
    assert tuned["size"] == "wide" and tuned["state_dict"]["head.weight"].shape[1] == 24
    # an explicit size that is not the init's is still refused, naming the file
    assert main([*argv, "--out", str(tmp_path / "small"), "--size", "small"]) != 0
    assert "holds a 'wide' network, not 'small'" in capsys.readouterr().err
