"""The fsr task through the CLI: generate, eval (classical and .npz), train, export, eval ONNX."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from synth.dataset import Dataset
from tactile_learn.cli import main


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_eval_triangulation_on_a_dataset_and_an_npz(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, _ = run(["generate", "--scene", "fsr6", "--n", "600", "--seed", "4", "--out", "d", "--quiet"], capsys)
    assert code == 0
    code, out, _ = run(["eval", "--task", "fsr", "--data", "d", "--method", "triangulation"], capsys)
    assert code == 0
    metrics = json.loads(out)["metrics"]
    for key in (
        "loc_err_mm_median",
        "loc_err_mm_p95",
        "force_err_pct_median",
        "force_accuracy",
        "detect_accuracy",
    ):
        for suffix in ("", "_inside", "_film"):
            assert f"{key}{suffix}" in metrics
    data = Dataset("d")
    np.savez("mine.npz", readings=data.array("readings"), xy_mm=data.array("xy_mm"), force_n=data.array("force_n"))
    code, out, _ = run(["eval", "--task", "fsr", "--data", "mine.npz", "--method", "triangulation"], capsys)
    assert code == 0
    assert json.loads(out)["metrics"]["loc_err_mm_median"] == pytest.approx(metrics["loc_err_mm_median"])
    np.savez(
        "bad.npz",
        readings=-data.array("readings") - 1,
        xy_mm=data.array("xy_mm"),
        force_n=data.array("force_n"),
    )
    code, _, err = run(["eval", "--task", "fsr", "--data", "bad.npz", "--method", "triangulation"], capsys)
    assert code == 2 and "negative" in err and len(err.strip().splitlines()) == 1


def test_train_export_and_eval_onnx(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("torch")
    pytest.importorskip("onnxruntime")
    for split, seed, n in (("train", 1, 2048), ("val", 2, 512)):
        code, _, _ = run(
            ["generate", "--scene", "fsr6", "--n", str(n), "--seed", str(seed), "--out", split, "--quiet"],
            capsys,
        )
        assert code == 0
    argv = ["train", "--task", "fsr", "--data", "train", "--val", "val", "--out", "run", "--epochs", "2"]
    code, _, err = run([*argv, "--threads", "1", "--quiet"], capsys)
    assert code == 0, err
    code, _, err = run(["export", "run", "--out", "models/fsr_tiny.onnx", "--test", "val"], capsys)
    assert code == 0, err
    card = json.loads(Path("models/fsr_tiny.json").read_text())
    assert card["task"] == "fsr"
    code, out, err = run(["eval", "--task", "fsr", "--data", "val", "--method", "models/fsr_tiny.onnx"], capsys)
    assert code == 0, err
    metrics = json.loads(out)["metrics"]
    assert np.isfinite(metrics["loc_err_mm_median_film"]) and 0.0 <= metrics["detect_accuracy_film"] <= 1.0
