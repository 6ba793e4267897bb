"""The one training loop for every task (CPU or one CUDA GPU, reproducible, resumable).

- Data streams from the dataset's memory-mapped shards, one shard in memory at a time, or is
  simulated as it is needed (``scene`` + ``stream``: :class:`tactile_learn.stream.TouchStream`).
- Epoch ``e`` shuffles and augments with ``SeedSequence(seed, spawn_key=(e,))``; the torch RNG
  state is checkpointed; so a run killed at any point and resumed with ``--resume`` ends with the
  same weights as an uninterrupted run with the same seed (same machine and thread count).
- Validation each epoch with the task's own metrics; the best epoch (task.primary_metric) is kept;
  early stopping after ``patience`` epochs without improvement.
- ``RUN/checkpoint.pt`` (everything to resume) is written atomically every epoch; ``RUN/model.pt``
  (best weights + what export needs), ``RUN/metrics.json`` and ``RUN/loss.png`` at the end.
- Multi-process (``torchrun --nproc-per-node N -m tactile_learn.cli train ...``): when torchrun's
  ``WORLD_SIZE`` is above 1 the same loop runs under ``DistributedDataParallel`` on the gloo backend
  (CPU). Every rank draws the same shuffled, augmented batches as one process would (the same
  random stream) and trains on its shard of each (rank ``r``: frames ``r, r + N, ...``); DDP
  averages the ranks' gradients, which for equal shards is the whole batch's gradient (up to the
  loss's per-batch normalisation), so the recipe - batch size, steps, schedule - is one process's
  and each rank computes 1/N of it. Rank 0 validates, decides the best epoch and early stopping for
  all ranks, and alone writes the checkpoint, ``model.pt`` and the metrics; the weights stay
  identical on every rank (``weights_sha256`` in the result).
"""

from __future__ import annotations

import copy
import hashlib
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from synth import __version__
from synth.errors import ConfigError, DataError
from synth.io import atomic_write_json
from synth.scene import Scene, load_scene, scene_differences
from tactile_learn.checkpoints import MODEL, load_torch, save_torch
from tactile_learn.distributed import TrainStep, broadcast, join_world, mean_over_ranks
from tactile_learn.progress import progress_bar
from tactile_learn.stream import TouchStream
from tactile_learn.tasks import get_task
from tactile_learn.tasks.base import EvalData, Task, readable_frames
from tactile_learn.torch_estimator import TorchEstimator
from tactile_learn.train_config import TrainConfig
from tactile_learn.train_distillation import PART_KEY, Teacher
from tactile_learn.training_sets import TrainingSet

__all__ = ["TrainConfig", "train"]

CHECKPOINT = "checkpoint.pt"
EPOCH_WEIGHTS = "epoch-{epoch:03d}.pt"  # train --keep-epochs


def _val_data(config: TrainConfig, train_set: TrainingSet | TouchStream) -> tuple[EvalData, float]:
    task = get_task(config.task)
    if config.val:
        # data without a scene of its own (recordings, an .npz) is read with the training scene
        own_scene = (Path(config.val) / "manifest.json").is_file()
        data = task.load_eval_data(config.val, None if own_scene else train_set.scene)
        if data.scene.digest != train_set.scene.digest:
            # a validation set of another scene would early-stop on the wrong physics
            differences = "; ".join(scene_differences(data.scene, train_set.scene))
            raise DataError(
                f"{config.val}: validation scene {data.scene.name!r} differs from the training scene "
                f"{train_set.scene.name!r} (validation vs training: {differences})"
            )
    else:
        raise ConfigError("--val: a validation dataset is required (generate one with another --seed)")
    # frames the sensor cannot read (a saturated ADC) cannot be validated on: left out, counted in
    # the run's metrics (``val_unreadable``)
    data, unreadable = readable_frames(task, data.subset(slice(0, config.val_limit)))
    return data, float(unreadable["share"])


def _loss_plot(history: list[dict[str, Any]], path: Path, metric: str) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from tactile_learn.bench_report import save_figure
    except ImportError:  # plotting is an optional extra
        return False
    epochs = [h["epoch"] for h in history]
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
    losses = [h["train_loss"] for h in history]
    ax[0].plot(epochs, losses, marker="o")
    # a log axis only where every loss is positive: a loss of zero (a frozen or already-converged run)
    # cannot be drawn on one
    scale = "log" if all(loss > 0 for loss in losses) else "linear"
    ax[0].set(xlabel="epoch", ylabel="training loss", yscale=scale, title="loss")
    ax[1].plot(epochs, [h["val"][metric] for h in history], marker="o", color="C1")
    ax[1].set(xlabel="epoch", ylabel=metric, title=f"validation {metric}")
    fig.tight_layout()
    save_figure(fig, path)
    return True


def weights_digest(state_dict: dict[str, torch.Tensor]) -> str:
    """SHA-256 of a network's weights (names and bytes): equal digests, equal networks."""
    digest = hashlib.sha256()
    for name in sorted(state_dict):
        digest.update(name.encode())
        digest.update(state_dict[name].detach().cpu().contiguous().numpy().tobytes())
    return digest.hexdigest()


def train(config: TrainConfig, resume: bool = False, progress: bool | None = None) -> dict[str, Any]:
    """Train ``config.task``'s network; returns the run's metrics (also in ``RUN/metrics.json``).

    Under torchrun with more than one process, data-parallel (module docstring)."""
    config.validate()
    rank, world, started = join_world()
    try:
        result = _train(config, resume, progress, rank, world)
        if world > 1:
            import torch.distributed as dist

            # rank 0 still writes the run after the last collective: a rank that tore the group
            # down meanwhile could abort inside gloo ("terminate called without an active exception")
            dist.barrier()
        return result
    finally:
        if started:
            import torch.distributed as dist

            dist.destroy_process_group()


@dataclass
class _Run:
    """One training run's working state: what the named steps of :func:`_train` share."""

    config: TrainConfig
    task: Task
    size: str
    epochs: int
    out: Path
    rank: int
    world: int
    train_set: TrainingSet | TouchStream
    folders: tuple[str, ...]
    keys: list[str]
    val: EvalData
    val_unreadable: float
    stats: dict[str, Any] = field(default_factory=dict)
    net: torch.nn.Module | None = None
    optimizer: Any = None
    scheduler: Any = None
    step_module: torch.nn.Module | None = None  # the DDP wrapper when more than one process trains
    teacher: Teacher | None = None  # distillation's teacher (tactile_learn.train_distillation)
    batches_per_epoch: int = 0
    state: dict[str, Any] = field(default_factory=dict)

    @property
    def lead(self) -> bool:
        return self.rank == 0

    @property
    def scene(self) -> Scene:
        return self.train_set.scene

    @property
    def checkpoint_path(self) -> Path:
        return self.out / CHECKPOINT


def _train(config: TrainConfig, resume: bool, progress: bool | None, rank: int, world: int) -> dict[str, Any]:
    if config.threads:
        torch.set_num_threads(config.threads)
    run = _open_run(config, rank, world, resume)
    _build_model(run)
    run.state = _resume_state(run) if resume else _fresh_state()
    started = time.perf_counter() - run.state["seconds"]
    # patience only counts once the one-cycle schedule has passed its peak and half its length:
    # before that a rising learning rate can stall validation without the run having converged
    patience_from = max(1, run.epochs // 2)

    def stale() -> int:
        return max(0, run.state["epoch"] - max(run.state["best_epoch"], patience_from))

    while run.state["epoch"] < run.epochs and stale() < config.patience:
        epoch = run.state["epoch"] + 1
        losses = _train_epoch(run, epoch, progress if run.lead else False)
        _end_epoch(run, epoch, losses, time.perf_counter() - started, progress)
    return _finish(run)


def _open_run(config: TrainConfig, rank: int, world: int, resume: bool) -> _Run:
    """The training data, the validation frames and the run folder, each checked."""
    task = get_task(config.task)
    train_set: TrainingSet | TouchStream
    if config.stream:
        train_set = TouchStream(
            load_scene(config.scene),
            config.stream,
            config.stream_seed,
            config.shard_size,
            config.fresh,
            config.stream_pixels or None,
        )
        folders: tuple[str, ...] = ()
        source = str(config.scene)
    else:
        folders = config.data_folders
        train_set = TrainingSet(folders, task.same_sensor)
        source = ", ".join(folders)
    scene = train_set.scene
    if scene.task != config.task:
        raise DataError(f"{source}: the scene is for task {scene.task!r}, not {config.task!r}")
    keys = list(task.train_keys_for(scene))
    missing = [k for k in keys if k not in train_set.keys]
    if missing:
        raise DataError(f"{source}: training needs arrays {', '.join(missing)} (generate with the default outputs)")
    val, val_unreadable = _val_data(config, train_set)
    run = _Run(
        config=config,
        task=task,
        size=config.size or task.net_sizes[0],
        epochs=config.epochs or task.default_epochs,
        out=Path(config.out),
        rank=rank,
        world=world,
        train_set=train_set,
        folders=folders,
        keys=keys,
        val=val,
        val_unreadable=val_unreadable,
    )
    # every rank checks before any writes (rank 0 creates the folder)
    occupied = broadcast(run.out.exists() and any(run.out.iterdir()), world)
    if occupied and not resume:
        raise DataError(f"{run.out} already holds a run: pass --resume to continue it, or choose another --out")
    if resume and not run.checkpoint_path.is_file():
        raise DataError(f"{run.checkpoint_path}: nothing to resume")
    if run.lead:
        run.out.mkdir(parents=True, exist_ok=True)
    return run


def _build_model(run: _Run) -> None:
    """Normalisation statistics, the network (fresh, or the ``--init`` weights), optimiser and schedule."""
    config, task, scene = run.config, run.task, run.scene
    source = ", ".join(run.folders) or str(config.scene)
    torch.manual_seed(config.seed)
    run.stats = task.fit_stats(run.train_set.arrays(run.keys, limit=task.stats_limit), scene)
    if config.init:
        # a fine-tuned network starts from its weights and keeps its normalisation (a mismatch is a
        # ModelError naming the file)
        start = TorchEstimator.from_checkpoint(config.init, scene)
        if not config.size:  # no --size: the fine-tune keeps the network it starts from
            run.size = str(start.checkpoint["size"])
        if start.checkpoint["size"] != run.size:
            raise ConfigError(
                f"--init: {config.init} holds a {start.checkpoint['size']!r} network, not {run.size!r} (pass --size)"
            )
        run.stats = dict(start.checkpoint["stats"])
        run.net = start.net
    else:
        run.net = task.build_net(run.size, scene, run.stats)
    run.net.to(config.device)  # before the optimiser, whose state follows the parameters' device
    run.optimizer = torch.optim.AdamW(run.net.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    batches_per_epoch = sum(int(s["n"]) // config.batch_size for s in run.train_set.shards)
    if config.max_batches:
        batches_per_epoch = min(batches_per_epoch, config.max_batches)
    if batches_per_epoch < 1:
        raise DataError(f"{source}: fewer samples than one batch of {config.batch_size}")
    if config.batch_size % run.world:
        # equal shards: the mean of the ranks' gradients is then the whole batch's gradient
        raise ConfigError(f"--batch-size: {config.batch_size} does not split into {run.world} equal shards (processes)")
    run.batches_per_epoch = batches_per_epoch
    if config.teacher:
        run.teacher = Teacher(config.teacher, scene, config.taught_parts(), config.teacher_weight, config.device)
    run.scheduler = torch.optim.lr_scheduler.OneCycleLR(
        run.optimizer, max_lr=config.lr, total_steps=run.epochs * batches_per_epoch, pct_start=0.15
    )
    if run.world > 1:
        from torch.nn.parallel import DistributedDataParallel

        if config.device != "cpu":
            raise ConfigError("--device: data-parallel training (torchrun) runs on the CPU only")

        # DDP broadcasts rank 0's initial weights, then averages the gradients of every step
        run.step_module = DistributedDataParallel(TrainStep(run.net, config.task))


def _fresh_state() -> dict[str, Any]:
    return {"epoch": 0, "best": None, "best_epoch": 0, "best_state": None, "history": [], "seconds": 0.0}


def _resume_state(run: _Run) -> dict[str, Any]:
    """Network, optimiser, schedule and torch RNG as the checkpoint left them; its loop state."""
    config = run.config
    ckpt = load_torch(run.checkpoint_path)
    # the thread count and the device may change on resume (a busier machine, a lent GPU): they
    # change speed, not the recipe
    same_recipe = ("threads", "device")
    started_with = {k: v for k, v in dict(ckpt.get("config") or {}).items() if k not in same_recipe}
    # a run started before a setting existed ran with that setting's default
    defaults = asdict(TrainConfig(task=config.task, data=config.data, out=config.out))
    started_with = {**{k: v for k, v in defaults.items() if k not in started_with}, **started_with}
    for name in same_recipe:
        started_with.pop(name, None)
    now = {k: v for k, v in asdict(config).items() if k not in same_recipe}
    if started_with != now:
        differ = sorted(k for k in started_with.keys() | now.keys() if started_with.get(k) != now.get(k))
        changes = "; ".join(f"{k}: {started_with.get(k)!r} then, {now.get(k)!r} now" for k in differ)
        raise ConfigError(
            f"{run.checkpoint_path}: the run was started with other settings ({changes}); "
            "resume it with the same command"
        )
    assert run.net is not None
    run.net.load_state_dict(ckpt["net"])
    run.optimizer.load_state_dict(ckpt["optimizer"])
    run.scheduler.load_state_dict(ckpt["scheduler"])
    torch.set_rng_state(ckpt["torch_rng"])
    state: dict[str, Any] = ckpt["state"]
    return state


def _train_epoch(run: _Run, epoch: int, show: bool | None) -> list[float]:
    """One epoch's optimiser steps; the batch losses."""
    config, task, net = run.config, run.task, run.net
    assert net is not None
    rng = np.random.default_rng(np.random.SeedSequence(config.seed, spawn_key=(epoch,)))
    net.train()
    losses: list[float] = []
    with progress_bar(run.batches_per_epoch, f"epoch {epoch}/{run.epochs}", "batch", enabled=show) as bar:
        if isinstance(run.train_set, TouchStream):
            batches = run.train_set.epoch_batches(epoch, run.keys, config.batch_size, rng, drop_last=True)
        else:
            part_key = PART_KEY if run.teacher is not None else None  # each frame's folder, for the teacher
            batches = run.train_set.iter_batches(
                run.keys, config.batch_size, rng=rng, drop_last=True, part_key=part_key
            )
        for i, arrays in enumerate(batches):
            if i >= run.batches_per_epoch:
                break
            if run.step_module is not None:
                # every rank draws the whole batch and its augmentation from the same random
                # stream (as one process would), then trains on its own shard of the frames
                x, targets = _batch(run, arrays, rng)
                x, targets = x[run.rank :: run.world], {k: v[run.rank :: run.world] for k, v in targets.items()}
                output = run.step_module(torch.from_numpy(np.ascontiguousarray(x)))
                targets = {k: np.ascontiguousarray(v) for k, v in targets.items()}
            else:
                x, targets = _batch(run, arrays, rng)
                output = task.train_forward(net, _on(torch.from_numpy(x), config.device))
            on_device = {k: _on(torch.from_numpy(v), config.device) for k, v in targets.items()}
            loss = task.loss(output, on_device, **config.loss_options())
            if not torch.isfinite(loss):
                raise DataError(f"training diverged at epoch {epoch} (loss {loss.item()}); lower --lr")
            run.optimizer.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), 5.0)
            run.optimizer.step()
            run.scheduler.step()
            losses.append(loss.item())
            bar.update()
            if i % 20 == 0:
                bar.set_postfix_str(f"loss {np.mean(losses[-20:]):.4g}")
    return losses


def _on(tensor: torch.Tensor, device: str) -> torch.Tensor:
    """``tensor`` on ``device`` (on the CPU the same tensor: the CPU path stays as it was)."""
    return tensor if device == "cpu" else tensor.to(device, non_blocking=True)


def _cpu_net(run: _Run) -> torch.nn.Module:
    """The network for validation, which runs on the CPU: itself, or a CPU copy of a GPU network."""
    assert run.net is not None
    return run.net if run.config.device == "cpu" else copy.deepcopy(run.net).cpu()


def _cpu_state(net: torch.nn.Module) -> dict[str, torch.Tensor]:
    """A copy of the weights on the CPU (what the run's files hold, whatever the device)."""
    return {k: v.detach().to("cpu", copy=True) for k, v in net.state_dict().items()}


def _batch(
    run: _Run, arrays: dict[str, np.ndarray], rng: np.random.Generator
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The task's augmented inputs and targets; with a teacher, its maps on the taught frames."""
    part = arrays.pop(PART_KEY, None)
    x, targets = run.task.training_batch(arrays, run.scene, rng)
    if run.teacher is not None and part is not None:
        key = run.task.output_key
        targets = {**targets, key: run.teacher.targets(x, targets[key], part)}
    return x, targets


def _end_epoch(run: _Run, epoch: int, losses: list[float], seconds: float, progress: bool | None) -> None:
    """Validate (rank 0, for everyone), keep the best weights, record the epoch, write the checkpoint."""
    state, net = run.state, run.net
    assert net is not None
    metric, higher_better = run.task.primary_metric
    val_net = _cpu_net(run)
    val_metrics = run.task.evaluate(TorchEstimator(val_net, run.config.task, run.scene), run.val) if run.lead else {}
    val_metrics = broadcast(val_metrics, run.world)
    value = float(val_metrics[metric])
    improved = state["best"] is None or (value > state["best"] if higher_better else value < state["best"])
    if improved:
        state["best"], state["best_epoch"] = value, epoch
        state["best_state"] = _cpu_state(net)
    state["epoch"] = epoch
    state["seconds"] = seconds
    state["history"].append(
        {"epoch": epoch, "train_loss": float(np.mean(losses)), "val": _scalars(val_metrics), "seconds": seconds}
    )
    if run.world > 1:
        state["history"][-1]["train_loss"] = mean_over_ranks(float(np.mean(losses)), run.world)
    if not run.lead:
        return
    if run.config.keep_epochs:
        save_torch(run.out / EPOCH_WEIGHTS.format(epoch=epoch), _weights_file(run, _cpu_state(net), {"epoch": epoch}))
    save_torch(
        run.checkpoint_path,
        {
            "config": asdict(run.config),
            "net": net.state_dict() if run.config.device == "cpu" else _cpu_state(net),
            "optimizer": run.optimizer.state_dict(),  # load_torch maps it to the CPU; resuming moves it
            "scheduler": run.scheduler.state_dict(),
            "torch_rng": torch.get_rng_state(),
            "state": state,
        },
    )
    if progress is not False:
        print(
            f"epoch {epoch}: loss {np.mean(losses):.4g}, val {metric} {value:.4f}{' (best)' if improved else ''}",
            flush=True,
        )


def _finish(run: _Run) -> dict[str, Any]:
    """The best epoch's weights, evaluated once more; rank 0 writes ``model.pt``, the metrics and the plot."""
    config, state, net, scene = run.config, run.state, run.net, run.scene
    assert net is not None
    net.cpu()  # the run's files and its final evaluation: CPU weights, whatever the device
    net.load_state_dict(state["best_state"])
    digest = weights_digest(state["best_state"])
    if not run.lead:
        # the other ranks hold the same weights; rank 0 writes the run
        return {"rank": run.rank, "world_size": run.world, "weights_sha256": digest, "epochs_run": state["epoch"]}
    final = _scalars(run.task.evaluate(TorchEstimator(net, config.task, scene), run.val))
    folders, train_set = run.folders, run.train_set
    result = {
        "task": config.task,
        "size": run.size,
        "scene": scene.name,
        "scene_digest": scene.digest,
        "val_unreadable": run.val_unreadable,
        "train_data": (
            train_set.describe()
            if isinstance(train_set, TouchStream)
            else {
                "path": folders[0] if len(folders) == 1 else list(folders),
                "seed": train_set.seeds[0] if len(folders) == 1 else train_set.seeds,
                "n": len(train_set),
            }
        ),
        "val_data": {"path": str(config.val), "n": len(run.val)},
        "epochs_run": state["epoch"],
        "best_epoch": state["best_epoch"],
        "train_seconds": state["seconds"],
        "threads": torch.get_num_threads(),
        "world_size": run.world,
        "weights_sha256": digest,
        "val_metrics": final,
        "history": state["history"],
        "config": asdict(config),
    }
    save_torch(run.out / MODEL, _weights_file(run, state["best_state"], result))
    atomic_write_json(run.out / "metrics.json", result)
    _loss_plot(state["history"], run.out / "loss.png", run.task.primary_metric[0])
    return result


def _weights_file(run: _Run, state_dict: dict[str, torch.Tensor], result: dict[str, Any]) -> dict[str, Any]:
    """What ``model.pt`` (and an epoch's ``epoch-NNN.pt``) holds: everything export and ``--init`` need."""
    return {
        "task": run.config.task,
        "size": run.size,
        "scene": run.scene.to_dict(),
        "stats": run.stats,
        "state_dict": state_dict,
        "result": result,
        "version": __version__,
    }


def _scalars(metrics: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in metrics.items() if isinstance(v, (int, float, dict))}


def default_threads() -> int:
    return max(1, min(2, os.cpu_count() or 1))
