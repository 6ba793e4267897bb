"""Resolve a ``--method`` value to an estimator: a classical method's name, a shipped model's
name (``models/<name>.onnx``), or the path of any ``.onnx`` model with its card."""

from __future__ import annotations

import os
from pathlib import Path

from synth.errors import ConfigError, ModelError
from synth.scene import Scene
from tactile_learn.estimators.base import Estimator
from tactile_learn.tasks import get_task

__all__ = ["available_methods", "model_dirs", "model_scene", "resolve_method", "shipped_models"]


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


def shipped_models(task: str) -> dict[str, Path]:
    """Shipped model names for ``task`` -> path of the ``.onnx`` file."""
    import json

    found: dict[str, Path] = {}
    for folder in model_dirs():
        if not folder.is_dir():
            continue
        for onnx_file in sorted(folder.glob("*.onnx")):
            card = onnx_file.with_suffix(".json")
            try:
                if json.loads(card.read_text()).get("task") == task:
                    found.setdefault(onnx_file.stem, onnx_file)
            except (OSError, ValueError):
                continue
    return found


def available_methods(task: str) -> list[str]:
    return [*get_task(task).classical_methods(), *shipped_models(task)]


def model_scene(task: str, spec: str) -> Scene | None:
    """The scene a model was trained on, when ``spec`` names a model (shipped name or ``.onnx``
    path) with a readable card; ``None`` for a classical method. Errors in the card surface when
    the model is resolved."""
    if spec in get_task(task).classical_methods():
        return None
    path = Path(spec) if Path(spec).suffix == ".onnx" else shipped_models(task).get(spec)
    if path is None or not path.is_file():
        return None
    from tactile_learn.runtime import OnnxEstimator

    try:  # no checksum here: resolve_method verifies the model when it loads it
        return OnnxEstimator(path, verify=False).card_scene_
    except ModelError:
        return None


def resolve_method(task: str, spec: str, scene: Scene, threads: int = 1) -> Estimator:
    """The estimator ``spec`` names for ``task`` on ``scene``, prepared."""
    task_obj = get_task(task)
    classical = task_obj.classical_methods()
    if spec in classical:
        return classical[spec](scene)
    path = Path(spec)
    if path.suffix != ".onnx":
        shipped = shipped_models(task)
        if spec not in shipped:
            raise ConfigError(
                f"--method: {spec!r} is not a method of task {task!r} "
                f"(available: {', '.join(available_methods(task))}, or a path to a .onnx model)"
            )
        path = shipped[spec]
    if not path.is_file():
        raise ModelError(f"--method: model file {path} not found")
    from tactile_learn.runtime import OnnxEstimator

    model = OnnxEstimator(path, threads=threads)
    if model.task_name != task:
        raise ModelError(f"{path}: the model is for task {model.task_name!r}, not {task!r}")
    if scene.digest != model.card_scene_.digest:
        # another scene of the same sensor (e.g. a calibrated copy): inputs are checked against it
        model = OnnxEstimator(path, threads=threads, scene=scene)
    return model.prepare()  # fails now, with a clear error, if the shapes do not match
