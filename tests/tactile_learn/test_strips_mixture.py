"""Training on several datasets of one sensor at once (a mixture of stimuli)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from synth.dataset import generate
from synth.errors import DataError
from synth.scene import load_scene
from tactile_learn.cli import main
from tactile_learn.tasks import get_task
from tactile_learn.training_sets import TrainingSet
from tests.paths import REPO_ROOT


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


@pytest.fixture(scope="module")
def mixture_run(folders: Path) -> Path:
    """A tiny network trained on two folders at once (the CLI)."""
    out = folders / "run"
    argv = ["train", "--task", "strips", "--data", str(folders / "mixed"), str(folders / "spheres")]
    argv += ["--val", str(folders / "val"), "--out", str(out), "--epochs", "1", "--batch-size", "50"]
    assert main([*argv, "--threads", "1", "--quiet", "--size", "tiny"]) == 0
    return out


def test_train_reads_several_folders(mixture_run: Path) -> None:
    metrics = json.loads((mixture_run / "metrics.json").read_text())
    assert metrics["train_data"]["n"] == 500 and metrics["train_data"]["seed"] == [2, 1]
    assert metrics["size"] == "tiny"


def test_averaged_weights_of_two_runs(folders: Path, mixture_run: Path) -> None:
    import torch

    from synth.errors import ModelError
    from tactile_learn.checkpoints import load_torch, load_weights

    sys.path.insert(0, str(REPO_ROOT / "scripts"))
    import average_weights

    first = mixture_run
    second = folders / "tuned"
    argv = ["train", "--task", "strips", "--data", str(folders / "mixed"), "--val", str(folders / "val")]
    argv += ["--out", str(second), "--epochs", "1", "--batch-size", "50", "--threads", "1", "--quiet"]
    assert main([*argv, "--size", "tiny", "--init", str(first), "--lr", "0.01"]) == 0
    out = folders / "soup"
    assert average_weights.main([str(first), str(second), "--weight", "0.25", "--last-epoch", "--out", str(out)]) == 0
    a, b = load_weights(first)["state_dict"], load_torch(second / "checkpoint.pt")["net"]
    soup = load_weights(out)["state_dict"]
    key = next(k for k in soup if soup[k].is_floating_point() and not torch.equal(a[k], b[k]))
    assert torch.allclose(soup[key], 0.75 * a[key] + 0.25 * b[key])
    assert not torch.allclose(soup[key], a[key])
    # the exported card says the weights are a soup, of which runs, at what weight
    onnx = folders / "soup.onnx"
    assert main(["export", str(out), "--out", str(onnx)]) == 0
    averaged = json.loads(onnx.with_suffix(".json").read_text())["training"]["averaged"]
    assert averaged["weight"] == 0.25 and averaged["last_epoch"] is True
    assert averaged["first"].endswith("run") and averaged["second"].endswith("tuned")
    with pytest.raises(ModelError, match="differ"):
        average_weights.main([str(first), "models/strips16.pt", "--out", str(folders / "bad")])
