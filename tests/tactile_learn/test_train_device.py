"""``train --device``: the network (and a distillation teacher) on a CUDA GPU, everything else as on the CPU."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed")

import torch

from synth.dataset import generate
from synth.errors import ConfigError, ModelError
from synth.scene import load_scene
from tactile_learn.checkpoints import load_torch, load_weights
from tactile_learn.cli import main
from tactile_learn.train import TrainConfig
from tests.paths import REPO_ROOT

CUDA = torch.cuda.is_available()


@pytest.fixture(scope="module")
def folders(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("device")
    generate(load_scene("strips16_mixed"), 100, 2, root / "mixed", shard_size=50)
    generate(load_scene("strips16"), 100, 1, root / "spheres", shard_size=50)
    generate(load_scene("strips16_mixed"), 50, 4, root / "val")  # validation shares the first folder's scene
    return root


def _train(folders: Path, out: str, *extra: str) -> dict:
    argv = ["train", "--task", "strips", "--data", str(folders / "mixed"), str(folders / "spheres")]
    argv += ["--val", str(folders / "val"), "--out", str(folders / out), "--epochs", "2", "--batch-size", "25"]
    argv += ["--threads", "1", "--quiet", "--size", "tiny", "--val-limit", "50", "--seed", "3"]
    assert main([*argv, *extra]) == 0
    return json.loads((folders / out / "metrics.json").read_text())


def _config(device: str) -> TrainConfig:
    return TrainConfig(task="strips", data="d", out="o", val="v", device=device)


@pytest.mark.parametrize("device", ["tpu", "cuda:x", "cuda:", "gpu:0", ""])
def test_an_unknown_device_is_named(device: str) -> None:
    with pytest.raises(ConfigError, match="--device"):
        _config(device).validate()


@pytest.mark.parametrize("device", ["cuda:", "cuda:1x"])
def test_a_malformed_index_is_named_even_with_a_gpu(monkeypatch: pytest.MonkeyPatch, device: str) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)  # as on a GPU machine
    with pytest.raises(ConfigError, match="neither cpu nor cuda"):
        _config(device).validate()


def test_cuda_without_a_gpu_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    with pytest.raises(ConfigError, match="no CUDA device"):
        _config("cuda").validate()


def test_device_cpu_is_the_default_run(folders: Path) -> None:
    """``--device cpu`` is the CPU path as it was: the same weights bit for bit, the device recorded."""
    plain = _train(folders, "plain")
    named = _train(folders, "named", "--device", "cpu")
    assert named["weights_sha256"] == plain["weights_sha256"]
    assert plain["config"]["device"] == named["config"]["device"] == "cpu"


def test_a_run_resumes_on_another_device_name(folders: Path) -> None:
    """The device changes speed, not the recipe: a checkpoint resumes under another --device (here cpu
    again, spelled as the recorded one was not) without the 'other settings' refusal."""
    first = _train(folders, "resume", "--epochs", "1")
    ckpt = load_torch(folders / "resume" / "checkpoint.pt")
    ckpt["config"]["device"] = "cuda"  # as if the first epoch had run on a GPU
    torch.save(ckpt, folders / "resume" / "checkpoint.pt")
    (folders / "resume" / "model.pt").unlink()
    argv = ["train", "--task", "strips", "--data", str(folders / "mixed"), str(folders / "spheres")]
    argv += ["--val", str(folders / "val"), "--out", str(folders / "resume"), "--epochs", "1", "--batch-size", "25"]
    argv += ["--threads", "1", "--quiet", "--size", "tiny", "--val-limit", "50", "--seed", "3", "--resume"]
    assert main(argv) == 0
    again = json.loads((folders / "resume" / "metrics.json").read_text())
    assert again["weights_sha256"] == first["weights_sha256"]


@pytest.mark.skipif(not CUDA, reason="needs a CUDA GPU (run on a lent GPU machine)")
def test_cuda_training_matches_the_cpu_recipe(folders: Path) -> None:
    """On a GPU, with a teacher: the run's files hold CPU weights, and training follows the CPU's
    run closely (same batches, same augmentation; only the arithmetic differs)."""
    _train(folders, "teacher_cpu", "--epochs", "1")
    extra = ["--teacher", str(folders / "teacher_cpu"), "--teacher-data", str(folders / "spheres")]
    cpu = _train(folders, "cpu", *extra)
    gpu = _train(folders, "gpu", *extra, "--device", "cuda")
    assert gpu["config"]["device"] == "cuda"
    saved = load_torch(folders / "gpu" / "model.pt")
    assert all(t.device.type == "cpu" for t in saved["state_dict"].values())
    reference = load_torch(folders / "cpu" / "model.pt")["state_dict"]
    for name, weight in saved["state_dict"].items():
        np.testing.assert_allclose(weight.numpy(), reference[name].numpy(), rtol=0, atol=2e-3, err_msg=name)
    for a, b in zip(cpu["history"], gpu["history"], strict=True):
        assert a["train_loss"] == pytest.approx(b["train_loss"], rel=1e-3)


def test_kept_epochs_and_their_average(folders: Path) -> None:
    """--keep-epochs writes every epoch's weights; model.pt is the best of them; scripts/strips_soup.py
    averages the last ones into a run folder that --init reads."""
    sys.path.insert(0, str(REPO_ROOT / "scripts"))
    import strips_soup

    result = _train(folders, "kept", "--keep-epochs")
    run = folders / "kept"
    files = sorted(run.glob("epoch-*.pt"))
    assert [f.name for f in files] == ["epoch-001.pt", "epoch-002.pt"]
    epochs = [load_weights(f)["state_dict"] for f in files]
    last = load_torch(run / "checkpoint.pt")["net"]
    best = load_weights(run)["state_dict"]
    for name in last:
        assert torch.equal(epochs[1][name], last[name])
        assert torch.equal(epochs[result["best_epoch"] - 1][name], best[name])
    assert any(not torch.equal(epochs[0][k], epochs[1][k]) for k in last)
    assert strips_soup.main([str(run), "--last", "2", "--out", str(folders / "soup")]) == 0
    soup = load_weights(folders / "soup")
    assert soup["result"]["train_data"] == result["train_data"]  # the run's record, for export's card
    assert soup["result"]["averaged"]["epochs"] == [str(f) for f in files]
    for name, weight in soup["state_dict"].items():
        if weight.is_floating_point():
            torch.testing.assert_close(weight, (epochs[0][name] + epochs[1][name]) / 2)
    _train(folders, "from_soup", "--epochs", "1", "--init", str(folders / "soup"))
    with pytest.raises(ConfigError, match="--last"):
        strips_soup.main([str(run), "--last", "3", "--out", str(folders / "soup3")])
    with pytest.raises(ModelError, match="--keep-epochs"):
        strips_soup.main([str(folders / "plain"), "--last", "1", "--out", str(folders / "soup4")])
