"""Provenance of recorded figures: portable paths and what regenerates a dataset."""

from __future__ import annotations

from pathlib import Path

import pytest

from synth.dataset import generate
from synth.scene import load_scene
from tactile_learn.provenance import command_line, dataset_record, portable_path


def test_paths_inside_the_working_folder_become_relative_and_others_only_their_name(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    assert portable_path(tmp_path / "data" / "x") == "data/x"
    assert portable_path("data/x") == "data/x"
    assert portable_path(Path("/elsewhere/models/m.onnx")) == "m.onnx"


def test_a_dataset_record_names_scene_seed_size_and_shard_size(tmp_path: Path) -> None:
    folder = tmp_path / "d"
    generate(load_scene("strips5"), 20, 4, folder, shard_size=8)
    record = dataset_record(folder, 20)
    scene = load_scene("strips5")
    assert record["scene"] == "strips5" and record["scene_digest"] == scene.digest
    assert (record["seed"], record["n"], record["shard_size"], record["n_frames"]) == (4, 20, 8, 20)
    assert record["path"] == "d"  # outside the working folder: its name, never a path of this machine


def test_a_folder_without_a_manifest_records_its_path_and_frames_only(tmp_path: Path) -> None:
    record = dataset_record(tmp_path / "recordings", 7)
    assert record == {"path": "recordings", "seed": None, "n_frames": 7}


def test_the_command_line_carries_no_machine_path(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("sys.argv", ["tactile-learn", "eval", "--data", str(tmp_path / "d"), "--json", "/x/y.json"])
    assert command_line() == "tactile-learn eval --data d --json y.json"
