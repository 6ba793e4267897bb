"""Data-parallel training under torchrun (gloo, CPU): the process group, rank 0's decisions shared
with every rank, and the module whose ``forward`` DDP synchronises. One process (no torchrun) needs
none of it: every helper is then a no-op. See :mod:`tactile_learn.train` for the recipe."""

from __future__ import annotations

import os
from typing import Any

import torch

from tactile_learn.tasks import get_task

__all__ = ["TrainStep", "broadcast", "join_world", "mean_over_ranks"]


class TrainStep(torch.nn.Module):
    """The task's training forward as a module's ``forward``: DDP synchronises gradients only for
    what runs through the wrapped module's ``forward`` (a general strip net's ``train_outputs``)."""

    def __init__(self, net: torch.nn.Module, task_name: str) -> None:
        super().__init__()
        self.net = net
        self.task_name = task_name

    def forward(self, x: torch.Tensor) -> Any:
        return get_task(self.task_name).train_forward(self.net, x)


def join_world() -> tuple[int, int, bool]:
    """(rank, world size, whether this call started the process group): torchrun's environment,
    joined to a gloo process group (one already started is used as it is); (0, 1, False) without it."""
    import torch.distributed as dist

    if int(os.environ.get("WORLD_SIZE", "1")) <= 1 and not dist.is_initialized():
        return 0, 1, False
    started = not dist.is_initialized()
    if started:
        dist.init_process_group("gloo")
    return dist.get_rank(), dist.get_world_size(), started


def broadcast(value: Any, world: int) -> Any:
    """Rank 0's ``value`` on every rank."""
    if world == 1:
        return value
    import torch.distributed as dist

    box = [value]
    dist.broadcast_object_list(box, src=0)
    return box[0]


def mean_over_ranks(value: float, world: int) -> float:
    import torch.distributed as dist

    tensor = torch.tensor([value], dtype=torch.float64)
    dist.all_reduce(tensor)
    return float(tensor.item()) / world
