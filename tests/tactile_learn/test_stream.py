"""Training on simulated-as-needed touches (tactile_learn.stream) against a written dataset."""

from __future__ import annotations

from itertools import islice
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed")

import torch

from synth.dataset import Dataset, generate, stream
from synth.errors import ConfigError
from synth.scene import load_scene
from tactile_learn.cli import main
from tactile_learn.stream import TouchStream
from tactile_learn.train import TrainConfig, train

WNS = load_scene("thermal_wns")
N, SHARD = 48, 16


@pytest.fixture(scope="module")
def folders(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("stream")
    generate(WNS, N, 7, root / "train", shard_size=SHARD)
    generate(WNS, 24, 8, root / "val", shard_size=SHARD)
    return root


def test_stream_shards_are_the_datasets_bytes(folders: Path) -> None:
    data = Dataset(folders / "train")
    for index, shard in enumerate(islice(stream(WNS, 7, SHARD), len(data.shards))):
        assert set(shard) == set(data.keys)
        for key in data.keys:
            assert np.array_equal(shard[key], data.shard(index, key)), key
    with pytest.raises(ConfigError, match="shard_size"):
        next(stream(WNS, 7, 0))


def _batches(source: Dataset | TouchStream, epoch: int, seed: int = 3) -> list[dict[str, np.ndarray]]:
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(epoch,)))
    keys = ["readings", "latent_material"]
    if isinstance(source, TouchStream):
        return list(source.epoch_batches(epoch, keys, 8, rng, drop_last=True))
    return list(source.iter_batches(keys, 8, rng=rng, drop_last=True))


def _same(a: list[dict[str, np.ndarray]], b: list[dict[str, np.ndarray]]) -> bool:
    return len(a) == len(b) and all(np.array_equal(x[k], y[k]) for x, y in zip(a, b, strict=True) for k in x)


def test_epochs_shuffle_like_the_dataset_and_fresh_epochs_are_new(folders: Path) -> None:
    data = Dataset(folders / "train")
    repeat = TouchStream(WNS, N, 7, SHARD, fresh=False)
    fresh = TouchStream(WNS, N, 7, SHARD)
    assert _same(_batches(repeat, 1), _batches(data, 1)) and _same(_batches(repeat, 2), _batches(data, 2))
    assert _same(_batches(fresh, 1), _batches(data, 1))
    second = _batches(fresh, 2)
    assert not _same(second, _batches(data, 2))
    # fresh epoch 2 holds new touches: none of its readings is one of epoch 1's
    seen = {r.tobytes() for b in _batches(fresh, 1) for r in b["readings"]}
    assert not any(r.tobytes() in seen for b in second for r in b["readings"])
    # seeded: the same seed gives the same touches, another seed others
    assert _same(_batches(TouchStream(WNS, N, 7, SHARD), 2), second)
    assert not _same(_batches(TouchStream(WNS, N, 9, SHARD), 1), _batches(data, 1))
    assert np.array_equal(repeat.arrays(["readings"], limit=20)["readings"], data.array("readings", 20))


def _config(folders: Path, out: str, **kw: object) -> TrainConfig:
    settings: dict[str, object] = {"epochs": 2, "batch_size": 16, "seed": 5, "val_limit": 64, "threads": 1}
    settings.update(kw)
    return TrainConfig(task="thermal", val=str(folders / "val"), out=str(folders / out), **settings)  # type: ignore[arg-type]


def _weights(run: Path) -> dict[str, torch.Tensor]:
    """The weights after the last epoch (model.pt keeps the best epoch's)."""
    return torch.load(run / "checkpoint.pt", weights_only=False)["net"]  # type: ignore[no-any-return]


def test_a_model_trained_from_the_stream_is_the_datasets(folders: Path) -> None:
    from_data = train(_config(folders, "run-data", data=str(folders / "train")), progress=False)
    streamed = _config(folders, "run-stream", data="", scene="thermal_wns", stream=N, stream_seed=7, shard_size=SHARD)
    from_stream = train(dataclass_replace(streamed, fresh=False), progress=False)
    a, b = _weights(folders / "run-data"), _weights(folders / "run-stream")
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    assert from_stream["val_metrics"] == from_data["val_metrics"]
    described = {"stream": "thermal_wns", "seed": 7, "n": N, "shard_size": SHARD, "fresh": False}
    assert from_stream["train_data"] == described
    fresh = train(dataclass_replace(streamed, out=str(folders / "run-fresh")), progress=False)
    c = _weights(folders / "run-fresh")
    assert any(not torch.equal(a[k], c[k]) for k in a)  # epoch 2 trained on other touches
    assert fresh["train_data"]["fresh"] is True
    from tactile_learn.export import export

    card = export(folders / "run-fresh", folders / "fresh.onnx")  # a run without a dataset path exports
    assert card["training"]["data"] == {**described, "fresh": True}


def dataclass_replace(config: TrainConfig, **changes: object) -> TrainConfig:
    from dataclasses import replace

    return replace(config, **changes)  # type: ignore[arg-type]


def test_cli_refuses_data_and_scene_mixed(folders: Path, capsys: pytest.CaptureFixture[str]) -> None:
    base = ["train", "--task", "thermal", "--val", str(folders / "val"), "--out", str(folders / "x")]
    assert main([*base, "--scene", "thermal_wns"]) != 0
    assert "--stream" in capsys.readouterr().err
    assert main([*base, "--data", str(folders / "train"), "--scene", "thermal_wns", "--stream", "32"]) != 0
    assert "either --data" in capsys.readouterr().err
    assert main([*base]) != 0
