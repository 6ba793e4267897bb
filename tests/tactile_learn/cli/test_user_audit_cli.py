"""Bad input a new user gives the CLI (results/user_audit.md): each case a clear one-line error, exit 2,
no traceback and nothing half-written. Each test failed before its fix."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from synth.dataset import load_arrays
from synth.errors import DataError
from tactile_learn.cli import main
from tactile_learn.idle import IdleGate


def fails_cleanly(argv: list[str], fragment: str, capsys: pytest.CaptureFixture[str]) -> str:
    code = main(argv)
    _, err = capsys.readouterr()
    assert code == 2, err
    assert fragment in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    return err


def strips5_frames(n: int) -> np.ndarray:
    return np.full((n, 10), 0.3, np.float32)


def test_run_refuses_a_file_without_frames(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the gate's active() failed on an empty batch (a reshape traceback)
    np.savez("empty.npz", readings=strips5_frames(0))
    argv = ["run", "--task", "strips", "--method", "strips5", "--frames", "empty.npz", "--out", "o.npz"]
    fails_cleanly(argv, "holds no frames", capsys)
    assert not Path("o.npz").exists()


def test_idle_gate_answers_an_empty_batch() -> None:
    gate = IdleGate.from_floor({"mean": [0.0] * 4, "sd": [1.0] * 4, "threshold": 3.0}, 4)
    assert gate.active(np.zeros((0, 4), np.float32)).shape == (0,)
    assert gate.active(np.array([[0.0, 0.0, 5.0, 0.0]], np.float32)).tolist() == [True]


@pytest.mark.parametrize(
    ("content", "fragment"),
    [
        ("truncated", "not a readable .npz file: truncated or corrupt"),
        ("text", "not a zip archive"),
        ("npy", "it is a single .npy array"),
        ("empty", "not a readable .npz file: it is empty"),
    ],
)
def test_unreadable_frame_files_are_named(
    content: str, fragment: str, workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # a truncated archive raised zipfile.BadZipFile (a traceback); a text file was "pickled data"
    np.savez("good.npz", readings=strips5_frames(40))
    whole = Path("good.npz").read_bytes()
    if content == "truncated":
        Path("f.npz").write_bytes(whole[: len(whole) // 2])
    elif content == "text":
        Path("f.npz").write_text("time,reading\n0,0.3\n")
    elif content == "npy":
        np.save("f.npy", strips5_frames(4))
        Path("f.npy").rename("f.npz")
    else:
        Path("f.npz").write_bytes(b"")
    with pytest.raises(DataError, match=re.escape(fragment)):
        load_arrays("f.npz")
    argv = ["run", "--task", "strips", "--method", "intersection", "--frames", "f.npz", "--out", "o.npz"]
    fails_cleanly(argv, fragment, capsys)
    assert not Path("o.npz").exists()


def test_a_damaged_member_of_an_npz_is_named(workdir: Path) -> None:
    # the zip's directory intact, an array's bytes flipped: zipfile's CRC check (BadZipFile)
    np.savez("good.npz", readings=strips5_frames(400))
    data = bytearray(Path("good.npz").read_bytes())
    data[200] ^= 0xFF
    Path("f.npz").write_bytes(bytes(data))
    with pytest.raises(DataError, match=r"f\.npz: not a readable \.npz file: truncated or corrupt"):
        load_arrays("f.npz")


def test_eval_refuses_nan_in_the_truth(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the metrics came out NaN (pearson_r 0, nrmse nan) with exit 0
    pressure = np.zeros((6, 5, 5), np.float32)
    pressure[4, 2, 2] = np.nan
    np.savez("e.npz", readings=strips5_frames(6), pressure=pressure)
    argv = ["eval", "--task", "strips", "--data", "e.npz", "--scene", "strips5", "--method", "intersection"]
    fails_cleanly(argv, "'pressure' holds NaN or inf (first in frame 4)", capsys)


def test_generate_into_a_file_is_refused_and_the_file_kept(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # mkdir raised FileExistsError (a traceback)
    Path("notes.txt").write_text("mine")
    argv = ["generate", "--scene", "strips5", "--n", "5", "--seed", "1", "--out", "notes.txt", "--quiet"]
    fails_cleanly(argv, "is a file, not a dataset folder", capsys)
    assert Path("notes.txt").read_text() == "mine"


def test_generate_refuses_zero_samples(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # --n 0 wrote an empty dataset with exit 0
    with pytest.raises(SystemExit) as exit_info:
        main(["generate", "--scene", "strips5", "--n", "0", "--seed", "1", "--out", "d", "--quiet"])
    assert exit_info.value.code == 2
    assert "--n: expected a positive integer" in capsys.readouterr().err
    assert not Path("d").exists()


def test_train_refuses_zero_epochs(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # --epochs 0 trained the task's default 12 epochs while the help called it "maximum epochs"
    with pytest.raises(SystemExit) as exit_info:
        main(["train", "--task", "strips", "--data", "d", "--val", "v", "--out", "r", "--epochs", "0"])
    assert exit_info.value.code == 2
    assert "--epochs: expected a positive integer" in capsys.readouterr().err
    assert not Path("r").exists()


def test_train_refuses_to_validate_on_a_training_folder(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the same folder as --data and --val validated on the training frames without a word
    assert main(["train", "--task", "strips", "--data", "d", "e", "--val", "./e", "--out", "r"]) == 2
    assert "--val: ./e is also a --data folder" in capsys.readouterr().err
    assert not Path("r").exists()


def test_simulate_help_gives_each_lattice_as_the_scene_has_it() -> None:
    # the help showed no capacitive stimulus: a user had to find geometry.lattice_shape in the code
    from synth.scene import load_scene
    from tactile_learn.cli.simulate import EXAMPLES

    strips = load_scene("strips16").sensor.geometry
    cap = load_scene("capacitive8").sensor.geometry
    fine = (strips.n_rows * strips.samples_per_pitch, strips.n_cols * strips.samples_per_pitch)
    assert f"strips16: {fine} cells of {strips.pitch_mm / strips.samples_per_pitch:g} mm" in EXAMPLES
    assert f"capacitive8: (F, {cap.lattice_shape[0]}, {cap.lattice_shape[1]}) cells of {cap.h_mm:g} mm" in EXAMPLES
    assert f"{cap.pad_cells} of them padding" in EXAMPLES


def test_a_scene_file_without_a_task_says_it_is_missing(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # an empty scene file said "task: None is not one of ..."
    Path("empty.toml").write_text("")
    argv = ["generate", "--scene", "empty.toml", "--n", "5", "--seed", "1", "--out", "d", "--quiet"]
    fails_cleanly(argv, "task: missing (a scene names its sensor: task = one of strips", capsys)
    assert not Path("d").exists()


def test_calibrate_names_the_tasks_that_have_a_calibration(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # --task strips raised NotImplementedError (a traceback)
    np.savez("p.npz", readings=strips5_frames(3))
    argv = ["calibrate", "--task", "strips", "--data", "p.npz", "--out", "s.toml"]
    fails_cleanly(
        argv, "--task strips: this sensor has no calibration (calibrate supports thermal, fsr, capacitive)", capsys
    )
    assert not Path("s.toml").exists()


def test_a_folder_that_is_not_a_dataset_says_so(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # a recordings folder given to calibrate --task fsr said only "no manifest.json"
    Path("touches").mkdir()
    Path("touches/touches.csv").write_text("file,material\n")
    argv = ["calibrate", "--task", "fsr", "--data", "touches", "--out", "film.toml"]
    fails_cleanly(argv, "no manifest.json (not a dataset folder: tactile-learn generate writes those", capsys)
    assert not Path("film.toml").exists()


def test_cards_verify_of_a_corrupt_model_fails_before_generating_anything(workdir: Path) -> None:
    # every held-out set was generated again (minutes for strips16) before each failed on the checksum
    import shutil

    from tactile_learn.cards import verify_card
    from tests.paths import REPO_ROOT

    shutil.copy(REPO_ROOT / "models" / "strips5.json", "s5.json")
    whole = (REPO_ROOT / "models" / "strips5.onnx").read_bytes()
    Path("s5.onnx").write_bytes(whole[: len(whole) // 2])
    report = verify_card("s5.onnx", workdir="work")
    assert not report["ok"] and report["sets"]
    assert all("checksum differs from its card's" in s["error"] for s in report["sets"].values())
    assert not Path("work").exists() or not any(Path("work").iterdir())


@pytest.mark.parametrize("rtol", ["-1", "nan", "inf", "tight"])
def test_cards_verify_refuses_a_tolerance_that_is_no_tolerance(
    rtol: str, workdir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # --rtol -1 ran the whole verification and failed every figure (exit 1, no word on why)
    with pytest.raises(SystemExit) as exit_info:
        main(["cards", "verify", "--model", "strips5", "--rtol", rtol])
    assert exit_info.value.code == 2
    assert f"--rtol: expected a non-negative number, got '{rtol}'" in capsys.readouterr().err


def test_bench_refuses_an_unknown_method(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # an unknown --method simulated the frames and printed an empty table, exit 0
    argv = ["bench", "--task", "strips", "--quick", "--n", "20", "--method", "intersectoin"]
    fails_cleanly(
        argv, "--method: 'intersectoin' is not a method of strips (available: intersection, projection", capsys
    )
    argv = ["bench", "--task", "strips", "--suite", "strips16_ood", "--n", "5", "--method", "nope"]
    fails_cleanly(argv, "--method: 'nope' is not a method of strips", capsys)


def test_python_entry_points_refuse_nonsense_arguments(tmp_path: Path) -> None:
    # each gave an untyped error or a silent wrong answer: AttributeError deep in a method (a scene of
    # another sensor, a card whose task is not its scene's), ValueError from range() (batch 0), the
    # first B - 1 samples for limit=-1, onnxruntime's "all cores" for threads=0
    import json
    import shutil

    from synth.dataset import Dataset, generate
    from synth.errors import ConfigError, ModelError
    from synth.scene import load_scene
    from tactile_learn.frame_stream import FrameStream
    from tactile_learn.methods import resolve_method
    from tactile_learn.runtime import OnnxEstimator
    from tests.paths import REPO_ROOT

    with pytest.raises(ConfigError, match="scene 'fsr6' is a 'fsr' scene, not a 'strips' one"):
        resolve_method("strips", "intersection", load_scene("fsr6"))
    models = REPO_ROOT / "models"
    for suffix in (".onnx", ".json"):
        shutil.copy(models / f"strips5{suffix}", tmp_path / f"s5{suffix}")
    card = json.loads((tmp_path / "s5.json").read_text())
    card["task"] = "fsr"
    (tmp_path / "s5.json").write_text(json.dumps(card))
    with pytest.raises(ModelError, match="the card's task 'fsr' is not its scene's 'strips'"):
        OnnxEstimator(tmp_path / "s5.onnx").prepare()
    for threads in (0, -1, 1.5):
        with pytest.raises(ConfigError, match="threads: expected a positive integer"):
            OnnxEstimator(models / "strips5.onnx", threads=threads).prepare()  # type: ignore[arg-type]
    stream = FrameStream(resolve_method("strips", "strips5", load_scene("strips5")))
    with pytest.raises(ConfigError, match="batch: expected a positive integer, got 0"):
        stream.run(strips5_frames(3), batch=0)
    assert stream.run(strips5_frames(3), batch=np.int64(2)).shape == (3, 5, 5)
    generate(load_scene("strips5"), 6, 1, tmp_path / "d")
    data = Dataset(tmp_path / "d")
    with pytest.raises(ConfigError, match="limit: expected a non-negative number of samples, got -1"):
        data.array("readings", limit=-1)
    assert len(data.array("readings", limit=np.int64(4))) == 4 and len(data.array("readings", limit=0)) == 0


@pytest.mark.parametrize("existing", [".onnx", ".json", ".pt"])
def test_export_keeps_a_model_already_at_out(existing: str, workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the README's and the help's example (--out models/strips16.onnx) replaced the shipped model,
    # its card and its weights without a word
    Path("models").mkdir()
    Path(f"models/strips16{existing}").write_text("shipped")
    argv = ["export", "runs/s16", "--out", "models/strips16.onnx"]
    fails_cleanly(argv, f"would replace strips16{existing}; choose another --out or pass --overwrite", capsys)
    assert Path(f"models/strips16{existing}").read_text() == "shipped"


def test_a_card_of_another_model_with_a_matching_checksum_is_named(tmp_path: Path) -> None:
    # the graph's own metadata is the last word: the message said only "built for scene X, its card says Y"
    import hashlib
    import json
    import shutil

    from synth.errors import ModelError
    from tactile_learn.runtime import OnnxEstimator
    from tests.paths import REPO_ROOT

    shutil.copy(REPO_ROOT / "models" / "strips16.onnx", tmp_path / "m.onnx")
    card = json.loads((REPO_ROOT / "models" / "strips5.json").read_text())
    card["model_sha256"] = hashlib.sha256((tmp_path / "m.onnx").read_bytes()).hexdigest()
    (tmp_path / "m.json").write_text(json.dumps(card))
    with pytest.raises(ModelError, match="the card belongs to another model or was edited"):
        OnnxEstimator(tmp_path / "m.onnx").prepare()
