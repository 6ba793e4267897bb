"""Resolve a ``--method`` value to an estimator: a classical method's name, a shipped model's
name (``models/<name>.onnx``), the path of any ``.onnx`` model with its card, or trained torch
weights (a finished run folder or a model's ``NAME.pt``: needs torch, imported only then)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from synth.errors import ConfigError, ModelError, TactileError
from synth.scene import Scene
from tactile_learn.estimators.base import Estimator
from tactile_learn.runtime import OnnxEstimator, read_card
from tactile_learn.tasks import get_task

__all__ = ["available_methods", "model_dirs", "model_scene", "resolve_method", "shipped_cards", "shipped_models"]


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


def available_methods(task: str) -> list[str]:
    return [*get_task(task).classical_methods(), *shipped_models(task)]


def _model_card(task: str, spec: str) -> tuple[Path, dict[str, Any]] | None:
    """The model ``spec`` names (a shipped model's name or a ``.onnx`` path) and its card; ``None``
    when it names no shipped model. A path's card is read (and checked) here."""
    if Path(spec).suffix == ".onnx":
        path = Path(spec)
        if not path.is_file():
            raise ModelError(f"--method: model file {path} not found")
        return path, read_card(path)
    return shipped_cards(task).get(spec)


def _is_weights(spec: str) -> bool:
    """``spec`` names torch weights: a ``.pt`` file or a finished (or unfinished) run folder."""
    path = Path(spec)
    return path.suffix == ".pt" or (path.is_dir() and any((path / f).is_file() for f in ("model.pt", "checkpoint.pt")))


def _torch_weights(task: str, spec: str, scene: Scene, threads: int) -> Estimator:
    """The network of a run folder or ``NAME.pt`` on ``scene`` (through the one weights loader)."""
    try:
        from tactile_learn.torch_estimator import TorchEstimator
    except ImportError:
        raise ConfigError(
            f"--method: {spec} holds torch weights, which need torch (pip install 'tactile-learn[train]'); "
            "export it to ONNX to run it without"
        ) from None
    estimator = TorchEstimator.from_checkpoint(spec, scene, threads=threads)
    if estimator.task_name != task:
        raise ModelError(f"{spec}: the weights are for task {estimator.task_name!r}, not {task!r}")
    return estimator


def model_scene(task: str, spec: str) -> Scene | None:
    """The scene a model was trained on, when ``spec`` names a model (shipped name or ``.onnx``
    path) with a readable card; ``None`` for a classical method. Errors in the card surface when
    the model is resolved."""
    if spec in get_task(task).classical_methods():
        return None
    if _is_weights(spec):
        try:
            from tactile_learn.checkpoints import load_weights, weights_scene

            return weights_scene(load_weights(spec))
        except (ImportError, TactileError):  # resolve_method says what is wrong
            return None
    try:
        found = _model_card(task, spec)
        if found is None:
            return None
        # no checksum here: resolve_method verifies the model when it loads it
        return OnnxEstimator(found[0], verify=False, card=found[1]).card_scene_
    except ModelError:
        return None


def resolve_method(task: str, spec: str, scene: Scene, threads: int = 1) -> Estimator:
    """The estimator ``spec`` names for ``task`` on ``scene``, prepared: a classical method built for
    ``scene``, or a model whose card is read once and whose file is verified against it now."""
    task_obj = get_task(task)
    if scene.task != task:  # every method reads its own sensor's config from the scene
        raise ConfigError(
            f"scene {scene.name!r} is a {scene.task!r} scene, not a {task!r} one (e.g. {task_obj.default_scene!r})"
        )
    classical = task_obj.classical_methods()
    if spec in classical:
        return classical[spec](scene)
    if _is_weights(spec):
        return _torch_weights(task, spec, scene, threads)
    found = _model_card(task, spec)
    if found is None:
        raise ConfigError(
            f"--method: {spec!r} is not a method of task {task!r} "
            f"(available: {', '.join(available_methods(task))}, or a path to a .onnx model)"
        )
    path, card = found
    if card["task"] != task:
        raise ModelError(f"{path}: the model is for task {card['task']!r}, not {task!r}")
    # another scene of the same sensor (e.g. a calibrated copy): inputs are checked against it
    own_scene = scene.digest == card["scene_digest"]
    model = OnnxEstimator(path, threads=threads, scene=None if own_scene else scene, card=card)
    # prepare verifies the file against its card and the shapes against the scene now, clearly
    return model.prepare()
