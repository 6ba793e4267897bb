"""Torch weights on disk: the one reader and writer of ``.pt`` files (imports torch).

Two kinds of file hold a trained network:

- ``RUN/model.pt``, written by :func:`tactile_learn.train.train` at the end of a run: the best
  weights plus everything export needs (task, scene, size, normalisation statistics, results);
- ``models/NAME.pt``, written by export beside ``NAME.onnx``: task, size, statistics and weights
  (its scene is in the card ``NAME.json`` beside it).

:func:`load_weights` reads either; :func:`build_net` turns what it read into the task's network in
eval mode. Checkpoints to resume training (``RUN/checkpoint.pt``) go through the same reader.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import torch

from synth.errors import DataError, ModelError
from synth.io import atomic_open
from synth.scene import Scene, parse_scene
from tactile_learn.tasks import get_task

__all__ = ["MODEL", "build_net", "load_torch", "load_weights", "save_torch", "weights_scene"]

#: a finished run's best model
MODEL = "model.pt"


def save_torch(path: str | Path, obj: Any) -> None:
    """``torch.save`` written atomically (a reader never sees half a file)."""
    buffer = io.BytesIO()
    torch.save(obj, buffer)
    with atomic_open(path, "wb") as handle:
        handle.write(buffer.getvalue())


def load_torch(path: str | Path) -> Any:
    """``torch.load`` on the CPU; an unreadable file is a :class:`DataError` naming it."""
    try:
        return torch.load(path, map_location="cpu", weights_only=False)
    except Exception as exc:  # torch raises assorted errors for truncated or foreign files
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise DataError(f"{path}: unreadable checkpoint ({reason})") from None


def load_weights(source: str | Path) -> dict[str, Any]:
    """A trained network's file: a finished run folder (``RUN/model.pt``) or a model's ``NAME.pt``."""
    path = Path(source)
    if path.is_dir():
        model = path / MODEL
        if not model.is_file():
            hint = " (training has not finished: rerun it with --resume)" if (path / "checkpoint.pt").exists() else ""
            raise DataError(f"{model}: no trained model{hint}")
        path = model
    elif not path.is_file():
        raise DataError(f"{path}: no such weights file")
    saved = load_torch(path)
    if not isinstance(saved, dict) or not {"task", "size", "stats", "state_dict"} <= set(saved):
        raise DataError(f"{path}: not a finished run or a model's weights file (NAME.pt)")
    saved.setdefault("source", str(path))
    return saved


def weights_scene(saved: dict[str, Any]) -> Scene:
    """The scene a network was trained on: in a run's ``model.pt``, else in the card beside ``NAME.pt``."""
    source = str(saved.get("source", "<weights>"))
    if "scene" in saved:
        return parse_scene(saved["scene"], source)
    from tactile_learn.runtime import read_card

    card = read_card(Path(source).with_suffix(".onnx"))
    if card["task"] != saved["task"]:
        raise ModelError(
            f"{source}: the weights are for task {saved['task']!r}, the card beside them for {card['task']!r}"
        )
    return parse_scene(card["scene"], str(Path(source).with_suffix(".json")))


def build_net(saved: dict[str, Any], scene: Scene | None = None) -> torch.nn.Module:
    """The task's network with the saved weights, in eval mode (``scene``: default the saved one)."""
    task = get_task(str(saved["task"]))
    scene = scene or weights_scene(saved)
    net = task.build_net(saved["size"], scene, saved["stats"])
    try:
        net.load_state_dict(saved["state_dict"])
    except RuntimeError as exc:  # shapes or names that do not fit this task's network of that size
        reason = str(exc).splitlines()[0]
        source = saved.get("source", "<weights>")
        raise ModelError(f"{source}: weights do not fit the {saved['size']!r} network ({reason})") from None
    net.eval()
    return net
