"""Multi-process training (DDP on gloo): two processes train, their weights agree, rank 0 writes the run."""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed")

import torch
import torch.distributed as dist
import torch.multiprocessing as mp

from synth.dataset import generate
from synth.scene import load_scene
from tactile_learn.checkpoints import load_weights
from tactile_learn.tasks import get_task
from tactile_learn.train import TrainConfig, train, weights_digest

WORLD = 2


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _rank_main(rank: int, port: int, config: TrainConfig, report: str) -> None:
    os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port), WORLD_SIZE=str(WORLD), RANK=str(rank))
    torch.set_num_threads(1)
    result = train(config, progress=False)  # joins (and leaves) the gloo group itself, as under torchrun
    Path(report, f"rank{rank}.json").write_text(json.dumps({k: result[k] for k in ("weights_sha256", "epochs_run")}))


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("ddp")
    scene = load_scene("strips5")
    generate(scene, 512, 1, root / "train", shard_size=256)
    generate(scene, 64, 2, root / "val")
    return root


def test_two_processes_train_and_agree(data: Path) -> None:
    config = TrainConfig(
        task="strips", data=str(data / "train"), val=str(data / "val"), out=str(data / "run"),
        epochs=2, batch_size=64, max_batches=4, seed=3, threads=1,
    )  # fmt: skip
    mp.spawn(_rank_main, args=(_free_port(), config, str(data)), nprocs=WORLD, join=True)
    reports = [json.loads((data / f"rank{r}.json").read_text()) for r in range(WORLD)]
    # the ranks end with the same weights: gradients were averaged on every step
    assert reports[0]["weights_sha256"] == reports[1]["weights_sha256"]
    assert [r["epochs_run"] for r in reports] == [2, 2]
    # rank 0 wrote the run (and only one of it), with those weights
    saved = load_weights(str(data / "run"))
    assert weights_digest(saved["state_dict"]) == reports[0]["weights_sha256"]
    metrics = json.loads((data / "run" / "metrics.json").read_text())
    assert metrics["world_size"] == WORLD
    # it trained: the weights moved from the seed's initial network, and the loss fell
    torch.manual_seed(config.seed)
    task = get_task("strips")
    initial = task.build_net("small", load_scene("strips5"), saved["stats"])
    assert weights_digest(initial.state_dict()) != reports[0]["weights_sha256"]
    losses = [h["train_loss"] for h in metrics["history"]]
    assert np.isfinite(losses).all() and losses[-1] < losses[0]
    assert not dist.is_initialized()  # this process never joined the group
