"""Training on several datasets of one sensor at once, and the separable forward model of the
exported strip networks."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from synth.dataset import generate
from synth.errors import DataError
from synth.scene import load_scene
from synth.sensors.strips import StripSensor
from tactile_learn.cli import main
from tactile_learn.nets.strips_deploy import SeparableStripForward
from tactile_learn.tasks import get_task
from tactile_learn.training_sets import TrainingSet


@pytest.fixture(scope="module")
def folders(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("mixture")
    generate(load_scene("strips16"), 300, 1, root / "spheres", shard_size=100)
    generate(load_scene("strips16_mixed"), 200, 2, root / "mixed", shard_size=100)
    generate(load_scene("strips16_mixed"), 100, 3, root / "val")
    generate(load_scene("strips5"), 100, 4, root / "strips5")
    return root


def test_a_training_set_interleaves_the_shards_of_every_folder(folders: Path) -> None:
    same = get_task("strips").same_sensor
    mixture = TrainingSet([str(folders / "mixed"), str(folders / "spheres")], same)
    assert len(mixture) == 500 and len(mixture.shards) == 5 and mixture.scene.name == "strips16_mixed"
    spheres = np.load(folders / "spheres" / "shard-00000.readings.npy")
    sources = []
    for batch in mixture.iter_batches(["readings"], 50, rng=np.random.default_rng(0)):
        # a batch comes from one shard; tell the two-sphere folder's first shard by its frames
        sources.append(bool((batch["readings"][:, None] == spheres[None]).all(axis=2).any(axis=1).all()))
    assert len(sources) == 10 and sum(sources) == 2
    # the order is shuffled across folders, not folder after folder
    orders = set()
    for seed in range(6):
        firsts = [b["readings"][0, 0] for b in mixture.iter_batches(["readings"], 100, rng=np.random.default_rng(seed))]
        orders.add(tuple(np.round(firsts, 6)))
    assert len(orders) > 1
    stats = mixture.arrays(["readings"], limit=100)["readings"]
    assert len(stats) == 100  # 40 + 60, each folder in proportion to its size


def test_a_training_set_refuses_another_sensor(folders: Path) -> None:
    same = get_task("strips").same_sensor
    with pytest.raises(DataError, match="another sensor"):
        TrainingSet([str(folders / "mixed"), str(folders / "strips5")], same)


def test_train_reads_several_folders(folders: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = folders / "run"
    argv = ["train", "--task", "strips", "--data", str(folders / "mixed"), str(folders / "spheres")]
    argv += ["--val", str(folders / "val"), "--out", str(out), "--epochs", "1", "--batch-size", "50"]
    assert main([*argv, "--threads", "1", "--quiet", "--size", "tiny"]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["train_data"]["n"] == 500 and metrics["train_data"]["seed"] == [2, 1]
    assert metrics["size"] == "tiny"


@pytest.mark.parametrize("scene_name", ["strips16", "strips5"])
def test_the_separable_forward_model_matches_the_dense_operators(scene_name: str) -> None:
    """Against the simulator's float64 operators (dense, ``cell_stress_operators``) on random maps
    up to 200 kPa: within 1e-3 of a strip's load noise. Two terms of the expansion would not be."""
    scene = load_scene(scene_name)
    sensor = StripSensor(scene.sensor)
    n, m = sensor.n_rows, sensor.n_cols
    rows_op, cols_op = sensor.array.cell_stress_operators()
    maps = np.random.default_rng(7).random((6, n, m)) ** 4 * 200.0
    flat = maps.reshape(6, n * m)
    stress = np.concatenate([flat @ rows_op.T, flat @ cols_op.T], axis=1).clip(0.0)
    gain = stress / (stress + scene.sensor.piezo.p0_kpa)
    want = np.concatenate([gain[:, : n * m].reshape(6, n, m).sum(2), gain[:, n * m :].reshape(6, n, m).sum(1)], 1)
    noise = float(sensor.load_noise().min())
    got = SeparableStripForward(scene)(torch.from_numpy(maps.astype(np.float32))).double().numpy()
    assert np.abs(got - want).max() < 1e-3 * noise
    coarse = SeparableStripForward(scene, rank=1)(torch.from_numpy(maps.astype(np.float32))).double().numpy()
    assert np.abs(coarse - want).max() > 1e-3 * noise  # the check can tell a truncated kernel
