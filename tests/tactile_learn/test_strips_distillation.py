"""Distillation in ``train``: a teacher's maps as the targets of some folders of a training set."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed")

from synth.dataset import generate
from synth.errors import ConfigError
from synth.scene import load_scene
from tactile_learn.cli import main
from tactile_learn.tasks import get_task
from tactile_learn.train import TrainConfig
from tactile_learn.train_distillation import PART_KEY, Teacher
from tactile_learn.training_sets import TrainingSet


@pytest.fixture(scope="module")
def folders(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("distill")
    generate(load_scene("strips16_mixed"), 100, 2, root / "mixed", shard_size=50)
    generate(load_scene("strips16"), 100, 1, root / "spheres", shard_size=50)
    generate(load_scene("strips16_mixed"), 50, 3, root / "val")
    generate(load_scene("strips16"), 50, 4, root / "val_spheres")  # validation shares the first folder's scene
    return root


def _train(folders: Path, out: str, *extra: str) -> dict:
    val = folders / "val_spheres"
    argv = ["train", "--task", "strips", "--val", str(val), "--out", str(folders / out), "--epochs", "1"]
    argv += ["--batch-size", "25", "--threads", "1", "--quiet", "--size", "tiny", "--val-limit", "50"]
    assert main([*argv, *extra]) == 0
    return json.loads((folders / out / "metrics.json").read_text())


@pytest.fixture(scope="module")
def teacher_run(folders: Path) -> Path:
    """A tiny network trained on the two-sphere folder: the teacher."""
    _train(folders, "teacher", "--data", str(folders / "spheres"))
    return folders / "teacher"


def test_batches_name_their_folder_without_changing_the_stream(folders: Path) -> None:
    same = get_task("strips").same_sensor
    mixture = TrainingSet([str(folders / "mixed"), str(folders / "spheres")], same)
    spheres = np.concatenate([np.load(p) for p in sorted((folders / "spheres").glob("shard-*.readings.npy"))])
    plain = list(mixture.iter_batches(["readings"], 20, rng=np.random.default_rng(5)))
    named = list(mixture.iter_batches(["readings"], 20, rng=np.random.default_rng(5), part_key=PART_KEY))
    assert len(plain) == len(named) == 8  # two whole batches per shard of 50
    for a, b in zip(plain, named, strict=True):
        np.testing.assert_array_equal(a["readings"], b["readings"])
        from_spheres = (b["readings"][:, None] == spheres[None]).all(axis=2).any(axis=1)
        np.testing.assert_array_equal(b[PART_KEY] == 1, from_spheres)
    # one folder: every frame is folder 0
    single = TrainingSet([str(folders / "spheres")], same)
    batch = next(single.iter_batches(["readings"], 20, rng=np.random.default_rng(0), part_key=PART_KEY))
    assert batch[PART_KEY].tolist() == [0] * 20


def test_the_teacher_replaces_only_the_taught_frames(folders: Path, teacher_run: Path) -> None:
    scene = load_scene("strips16_mixed")
    teacher = Teacher(str(teacher_run), scene, taught=[1], weight=0.25)

    def first4(key: str) -> np.ndarray:
        return np.concatenate([np.load(folders / f / f"shard-00000.{key}.npy")[:4] for f in ("mixed", "spheres")])

    readings, truth = first4("readings").astype(np.float32), first4("pressure").astype(np.float32)
    part = np.array([0, 0, 0, 0, 1, 1, 1, 1])
    out = teacher.targets(readings, truth, part)
    np.testing.assert_array_equal(out[:4], truth[:4])
    expected = 0.25 * teacher.maps(readings[4:]) + 0.75 * truth[4:]
    np.testing.assert_allclose(out[4:], expected, rtol=1e-6, atol=1e-6)
    assert not np.allclose(out[4:], truth[4:])
    # nothing taught in the batch: the targets as given
    assert teacher.targets(readings, truth, np.zeros(8, dtype=int)) is truth


def test_distillation_changes_the_targets_of_training(folders: Path, teacher_run: Path) -> None:
    """A student that starts as the teacher, taught by it: its final map's loss is 0 on the taught
    frames (the intermediate map's is not), so the epoch's loss is far below the same run on the truth."""
    common = ["--data", str(folders / "spheres"), "--init", str(teacher_run), "--lr", "1e-7"]
    plain = _train(folders, "plain", *common)
    teach = ["--teacher", str(teacher_run), "--teacher-data", str(folders / "spheres")]
    taught = _train(folders, "taught", *common, *teach)
    assert taught["config"]["teacher"] == str(teacher_run)
    plain_loss, taught_loss = plain["history"][0]["train_loss"], taught["history"][0]["train_loss"]
    assert taught_loss < 0.6 * plain_loss


def test_bad_distillation_settings_are_refused(folders: Path) -> None:
    data = (str(folders / "mixed"), str(folders / "spheres"))
    out, teacher = str(folders / "never"), "models/strips16_spheres.pt"

    def config(**kw: object) -> TrainConfig:
        return TrainConfig(task="strips", data=data, out=out, **kw)  # type: ignore[arg-type]

    with pytest.raises(ConfigError, match="teacher-data"):
        config(teacher=teacher, teacher_data=(str(folders / "val"),)).validate()
    with pytest.raises(ConfigError, match="teacher-data"):
        config(teacher=teacher).validate()
    with pytest.raises(ConfigError, match="teacher-weight"):
        config(teacher=teacher, teacher_data=data[1:], teacher_weight=1.5).validate()
    with pytest.raises(ConfigError, match="needs --teacher"):
        config(teacher_data=data[1:]).validate()
    good = config(teacher=teacher, teacher_data=data[1:])
    good.validate()
    assert good.taught_parts() == [1]
