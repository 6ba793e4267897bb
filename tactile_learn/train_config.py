"""What one training run is asked to do (:class:`TrainConfig`), checked before any data is read.

Kept apart from the loop (:mod:`tactile_learn.train`) so the run's settings and their checks read on
their own; torch is imported only to ask whether a CUDA device exists (``--device cuda``)."""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from pathlib import Path

from synth.errors import ConfigError
from tactile_learn.tasks import get_task

__all__ = ["TrainConfig"]


@dataclass(frozen=True)
class TrainConfig:
    task: str
    data: str | tuple[str, ...]  # a dataset folder, or several of one sensor read as one training set
    out: str
    val: str | None = None
    size: str = ""
    epochs: int = 0  # 0: the task's default
    batch_size: int = 256
    lr: float = 3e-3
    weight_decay: float = 1e-4
    seed: int = 0
    patience: int = 6
    val_limit: int = 4000
    threads: int = 0  # 0: torch's default
    max_batches: int = 0  # per epoch; 0: the whole dataset (tests use a few)
    init: str | None = None  # start from these weights (a run folder or a model's NAME.pt): fine-tuning
    # instead of ``data``: simulate ``stream`` samples per epoch of ``scene`` (tactile_learn.stream)
    scene: str = ""
    stream: int = 0
    stream_seed: int = 0
    shard_size: int = 8192
    fresh: bool = True  # a new ``stream`` samples every epoch (False: the same ones, as a dataset)
    stream_pixels: int = 0  # thermal: simulate only this many random pixels per touch (0: all)
    # distillation (tactile_learn.train_distillation): these weights' outputs are the targets of the frames
    # of the ``teacher_data`` folders (each one of ``data``), blended with the truth at ``teacher_weight``
    teacher: str | None = None
    teacher_data: tuple[str, ...] = ()
    teacher_weight: float = 1.0
    # the weight of the loss's per-frame (1 - r) term, for tasks whose loss has one (strips)
    r_weight: float = 1.0
    # where the network (and a teacher) computes: "cpu", or "cuda"/"cuda:N" for a GPU. Batches,
    # augmentation and validation stay the same code on the CPU; only the forward and backward
    # passes move. Not bit-identical across devices (other kernels): the recipe is the same.
    device: str = "cpu"
    # also write every epoch's weights as RUN/epoch-NNN.pt (a weights file like model.pt): the
    # material of an average over the last epochs (scripts/strips_soup.py)
    keep_epochs: bool = False

    def validate(self) -> None:
        task = get_task(self.task)
        if self.size and self.size not in task.net_sizes:
            raise ConfigError(f"--size: {self.size!r} is not one of {', '.join(task.net_sizes)}")
        for name in ("batch_size", "patience", "val_limit"):
            if getattr(self, name) < 1:
                raise ConfigError(f"--{name.replace('_', '-')}: must be positive")
        if not (0 < self.lr < 1):
            raise ConfigError(f"--lr: {self.lr} is out of range (0, 1)")
        if self.epochs < 0 or self.seed < 0 or self.threads < 0 or self.max_batches < 0:
            raise ConfigError("--epochs, --seed, --threads and --max-batches must be non-negative")
        if self.stream < 0 or self.stream_seed < 0 or self.shard_size < 1:
            raise ConfigError("--stream and --stream-seed must be non-negative, --shard-size positive")
        if bool(self.stream) == bool(self.data):
            raise ConfigError("give either --data (a dataset folder) or --scene with --stream N (touches per epoch)")
        if bool(self.stream) != bool(self.scene):
            raise ConfigError("--stream N needs --scene (the scene to simulate), and --scene needs --stream")
        if self.stream_pixels < 0 or (self.stream_pixels and not self.stream):
            raise ConfigError("--stream-pixels K: a positive pixel count, with --scene and --stream")
        self._validate_teacher()
        training = {Path(f).resolve() for f in self.data_folders} if self.data else set()
        if self.val and Path(self.val).resolve() in training:
            # early stopping and the recorded validation figures would read frames the network learns
            raise ConfigError(
                f"--val: {self.val} is also a --data folder; validate on frames the network does not train on "
                "(generate them with another --seed)"
            )
        if not (0.0 <= self.r_weight <= 100.0):
            raise ConfigError(f"--r-weight: {self.r_weight} is out of range [0, 100]")
        if self.r_weight != 1.0 and "r_weight" not in inspect.signature(task.loss).parameters:
            raise ConfigError(f"--r-weight: the {self.task} task's loss has no per-frame r term")
        self._validate_device()

    def _validate_device(self) -> None:
        if self.device == "cpu":
            return
        kind, colon, index = self.device.partition(":")
        if kind != "cuda" or (colon and not index.isdigit()):  # "cuda" or "cuda:N", not "cuda:"
            raise ConfigError(f"--device: {self.device!r} is neither cpu nor cuda[:N]")
        import torch  # only here: the settings themselves need no torch

        if not torch.cuda.is_available():
            raise ConfigError(f"--device {self.device}: torch sees no CUDA device on this machine (use --device cpu)")
        if index and int(index) >= torch.cuda.device_count():
            raise ConfigError(f"--device {self.device}: this machine has {torch.cuda.device_count()} CUDA device(s)")

    @property
    def data_folders(self) -> tuple[str, ...]:
        """``data`` as a tuple of folders (one folder may be given as a string)."""
        return (self.data,) if isinstance(self.data, str) else tuple(self.data)

    def loss_options(self) -> dict[str, float]:
        """Keyword arguments of the task's loss (none at the defaults: every task's loss takes those)."""
        return {} if self.r_weight == 1.0 else {"r_weight": self.r_weight}

    def _validate_teacher(self) -> None:
        if not self.teacher:
            if self.teacher_data:
                raise ConfigError("--teacher-data needs --teacher (the network that teaches those folders)")
            return
        if self.stream:
            raise ConfigError("--teacher: distillation reads datasets (--data), not a --stream")
        folders = self.data_folders
        strange = [f for f in self.teacher_data if f not in folders]
        if not self.teacher_data or strange:
            raise ConfigError(
                f"--teacher-data: name one or more of the --data folders ({', '.join(folders)})"
                + (f"; not one of them: {', '.join(strange)}" if strange else "")
            )
        if not (0.0 < self.teacher_weight <= 1.0):
            raise ConfigError(f"--teacher-weight: {self.teacher_weight} is out of range (0, 1]")

    def taught_parts(self) -> list[int]:
        """Indices (in ``data``'s order) of the folders the teacher teaches: a folder given twice is taught twice."""
        return [i for i, f in enumerate(self.data_folders) if f in self.teacher_data]
