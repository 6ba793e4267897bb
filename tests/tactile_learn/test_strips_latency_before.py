"""scripts/strips_latency.py ``--before DIR`` finds the same model in DIR whether it was named as a
shipped model or given as an .onnx path (a run's export): the path's file name, not ``<path>.onnx``."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np

from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_latency

SHIPPED = "strips16_small"


def test_before_file_name_of_a_name_and_of_a_path() -> None:
    assert strips_latency.before_file_name(SHIPPED) == f"{SHIPPED}.onnx"
    assert strips_latency.before_file_name("runs/candidate/model.onnx") == "model.onnx"


def test_a_model_path_is_timed_beside_its_namesake_in_the_before_folder(tmp_path: Path) -> None:
    run = tmp_path / "run"
    before = tmp_path / "before"
    for folder in (run, before):
        folder.mkdir()
        shutil.copyfile(REPO_ROOT / "models" / f"{SHIPPED}.onnx", folder / "model.onnx")
        shutil.copyfile(REPO_ROOT / "models" / f"{SHIPPED}.json", folder / "model.json")
    model = str(run / "model.onnx")
    out = tmp_path / "latency.json"
    argv = ["--models", model, "--before", str(before), "--rounds", "2", "--per-round", "1", "--json", str(out)]
    assert strips_latency.main(argv) == 0
    timed = json.loads(out.read_text())["median_us"]
    assert f"{model} (before)" in timed and timed[f"{model} (before)"] > 0


def test_a_suites_frames_are_spread_over_its_families() -> None:
    from synth.suite import load_suite
    from tactile_learn.suites import suite_eval_data

    frames = strips_latency.timing_frames("strips16_unseen4", n=30)
    suite = load_suite("strips16_unseen4")
    each = -(-30 // len(suite.families))
    first = next(iter(suite_eval_data(suite, each, 909090).values())).inputs
    assert frames.shape == (30, 32) and frames.dtype == np.float32
    np.testing.assert_array_equal(frames[:each], first)
    assert strips_latency.timing_frames(None, n=8).shape == (8, 32)
