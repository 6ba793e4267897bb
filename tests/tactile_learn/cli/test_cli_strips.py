"""CLI round trips for the strip task, called through main(argv) like a user would."""

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


def test_generate_then_eval_round_trip(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(
        ["generate", "--scene", "strips5", "--n", "300", "--seed", "4", "--out", "d", "--shard-size", "128"],
        capsys,
    )
    assert code == 0 and "wrote 300 samples" in out
    code, out, _ = run(
        ["eval", "--task", "strips", "--data", "d", "--method", "intersection", "--json", "r.json"], capsys
    )
    assert code == 0
    result = json.loads(Path("r.json").read_text())
    assert result == json.loads(out) | {"seconds": result["seconds"]}
    assert result["task"] == "strips" and result["method"] == "intersection" and result["n_frames"] == 300
    assert {"pearson_r_mean", "pearson_r_median", "nrmse", "peak_err_mm_median"} <= set(result["metrics"])
    assert 0.5 < result["metrics"]["pearson_r_mean"] <= 1.0
    # the same frames as a user's .npz give the same metrics
    data = Dataset("d")
    np.savez("mine.npz", readings=data.array("readings"), pressure=data.array("pressure"))
    code, out, _ = run(
        ["eval", "--task", "strips", "--data", "mine.npz", "--scene", "strips5", "--method", "intersection"],
        capsys,
    )
    assert code == 0
    mine = json.loads(out)["metrics"]
    for key in ("pearson_r_mean", "nrmse", "peak_err_mm_median"):
        assert mine[key] == pytest.approx(result["metrics"][key])


def test_noise_off_gives_clean_readings(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert (
        run(
            [
                "generate",
                "--scene",
                "strips5",
                "--n",
                "50",
                "--seed",
                "1",
                "--out",
                "clean",
                "--noise",
                "off",
            ],
            capsys,
        )[0]
        == 0
    )
    data = Dataset("clean")
    assert np.array_equal(data.array("readings"), data.array("readings_clean"))
    assert data.scene.noise is False


def test_simulate_a_user_field(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    field = np.zeros((20, 20), np.float32)  # strips5: 5 x 5 strips, 4 cells per pitch
    field[8:12, 8:12] = 50.0
    np.savez("field.npz", pressure=field)
    code, _, _ = run(["simulate", "--scene", "strips5", "--pressure", "field.npz", "--out", "r.npz"], capsys)
    assert code == 0
    with np.load("r.npz") as r:
        assert r["readings"].shape == (10,) and r["pressure"].shape == (5, 5)
        assert r["pressure"][2, 2] == pytest.approx(50.0) and r["pressure"][0, 0] == 0
        assert r["readings"][2] == r["readings"].max()


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["generate", "--scene", "nope", "--n", "5", "--seed", "1", "--out", "x"], "unknown scene 'nope'"),
        (["eval", "--task", "strips", "--data", "missing.npz", "--method", "intersection"], "no such file"),
        (
            ["eval", "--task", "strips", "--data", "bad.npz", "--method", "intersection"],
            "needs arrays 'readings'",
        ),
        (["eval", "--task", "strips", "--data", "nan.npz", "--method", "intersection"], "NaN"),
        (["eval", "--task", "strips", "--data", "ok.npz", "--method", "magic"], "is not a method of task"),
        (
            ["eval", "--task", "strips", "--data", "ok.npz", "--method", "absent.onnx"],
            "absent.onnx not found",
        ),
        (["eval", "--task", "strips", "--data", "wrong.npz", "--method", "intersection"], "pass --scene"),
        (["simulate", "--scene", "strips5", "--pressure", "neg.npz", "--out", "o.npz"], "negative pressure"),
        (
            ["simulate", "--scene", "strips5", "--pressure", "shape.npz", "--out", "o.npz"],
            "expected shape (B, 20, 20)",
        ),
    ],
)
def test_errors_are_one_line_and_exit_2(
    argv: list[str], fragment: str, workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    readings = np.full((4, 32), 0.3, np.float32)
    np.savez("ok.npz", readings=readings, pressure=np.zeros((4, 16, 16), np.float32))
    np.savez("bad.npz", values=readings)
    nan = readings.copy()
    nan[2, 3] = np.nan
    np.savez("nan.npz", readings=nan, pressure=np.zeros((4, 16, 16), np.float32))
    np.savez("wrong.npz", readings=np.full((4, 10), 0.3, np.float32), pressure=np.zeros((4, 5, 5), np.float32))
    np.savez("neg.npz", pressure=-np.ones((20, 20), np.float32))
    np.savez("shape.npz", pressure=np.ones((21, 20), np.float32))
    code, _, err = run(argv, capsys)
    assert code == 2, err
    assert fragment in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_scenes_lists_and_shows(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["scenes"], capsys)
    assert code == 0 and "strips16" in out and "strips5" in out
    code, out, _ = run(["scenes", "--show", "strips5"], capsys)
    Path("copy.toml").write_text(out)
    code, out, _ = run(["generate", "--scene", "copy.toml", "--n", "10", "--seed", "1", "--out", "c"], capsys)
    assert code == 0
    from synth.scene import load_scene

    assert Dataset("c").scene.digest == load_scene("strips5").digest
