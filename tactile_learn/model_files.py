"""Where ONNX models are found and how one becomes a prepared estimator: the shipped models' folders, a
``--method`` value that names a model (a shipped name or a ``.onnx`` path) and its card.

Below :mod:`tactile_learn.methods` (which adds classical methods, torch weights and known-objects bundles) so
that :mod:`tactile_learn.known_objects` can load a bundle's models the same way without importing it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from synth.errors import ModelError
from synth.scene import Scene
from tactile_learn.runtime import OnnxEstimator, read_card

__all__ = ["model_card", "model_dirs", "onnx_method", "shipped_cards", "shipped_models"]


def model_dirs() -> list[Path]:
    """Where shipped models are looked up: ``$TACTILE_LEARN_MODELS``, ``./models``, and the
    ``models/`` folder beside the installed package (a source checkout)."""
    dirs = []
    if os.environ.get("TACTILE_LEARN_MODELS"):
        dirs.append(Path(os.environ["TACTILE_LEARN_MODELS"]))
    dirs.append(Path.cwd() / "models")
    dirs.append(Path(__file__).resolve().parent.parent / "models")
    unique: list[Path] = []
    for d in dirs:
        if d.resolve() not in [u.resolve() for u in unique]:
            unique.append(d)
    return unique


def shipped_cards(task: str) -> dict[str, tuple[Path, dict[str, Any]]]:
    """Shipped models of ``task``: name -> (path of the ``.onnx`` file, its card, read once). A model
    whose card is missing or unreadable is not offered (``eval --method PATH`` names the problem)."""
    found: dict[str, tuple[Path, dict[str, Any]]] = {}
    for folder in model_dirs():
        if not folder.is_dir():
            continue
        for onnx_file in sorted(folder.glob("*.onnx")):
            if onnx_file.stem in found:
                continue
            try:
                card = read_card(onnx_file)
            except ModelError:
                continue
            if card["task"] == task:
                found[onnx_file.stem] = (onnx_file, card)
    return found


def shipped_models(task: str) -> dict[str, Path]:
    """Shipped model names for ``task`` -> path of the ``.onnx`` file."""
    return {name: path for name, (path, _) in shipped_cards(task).items()}


def model_card(task: str, spec: str) -> tuple[Path, dict[str, Any]] | None:
    """The model ``spec`` names (a shipped model's name or a ``.onnx`` path) and its card; ``None``
    when it names no shipped model. A path's card is read (and checked) here."""
    if Path(spec).suffix == ".onnx":
        path = Path(spec)
        if not path.is_file():
            raise ModelError(f"--method: model file {path} not found")
        return path, read_card(path)
    return shipped_cards(task).get(spec)


def onnx_method(task: str, path: Path, card: dict[str, Any], scene: Scene, threads: int) -> OnnxEstimator:
    """The ONNX model at ``path`` (its ``card`` already read) on ``scene``, prepared: the file verified against
    its card and the shapes against the scene now, clearly."""
    if card["task"] != task:
        raise ModelError(f"{path}: the model is for task {card['task']!r}, not {task!r}")
    # another scene of the same sensor (e.g. a calibrated copy): inputs are checked against it
    own_scene = scene.digest == card["scene_digest"]
    return OnnxEstimator(path, threads=threads, scene=None if own_scene else scene, card=card).prepare()
