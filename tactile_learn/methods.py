"""Resolve a ``--method`` value to an estimator: a classical method's name, a shipped model's
name (``models/<name>.onnx``), the path of any ``.onnx`` model with its card, a known-objects
bundle (:mod:`tactile_learn.known_objects`: its ``bundle.json`` or folder), a learned object's folder
(:mod:`tactile_learn.learned_objects`: its specialist), or trained torch weights (a finished run folder or
a model's ``NAME.pt``: needs torch, imported only then)."""

from __future__ import annotations

from pathlib import Path

from synth.errors import ConfigError, ModelError, TactileError
from synth.scene import Scene
from tactile_learn.estimators.base import Estimator
from tactile_learn.known_objects import bundle_method, default_model_spec, is_bundle, read_bundle
from tactile_learn.learned_objects import is_learned_object, learned_specialist
from tactile_learn.model_files import model_card, model_dirs, onnx_method, shipped_cards, shipped_models
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.tasks import get_task

__all__ = ["available_methods", "model_dirs", "model_scene", "resolve_method", "shipped_cards", "shipped_models"]


def available_methods(task: str) -> list[str]:
    return [*get_task(task).classical_methods(), *shipped_models(task)]


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
    if is_bundle(spec):  # a known-objects bundle: its default model's scene
        try:
            folder, bundle = read_bundle(spec)
        except ModelError:  # resolve_method says what is wrong
            return None
        return model_scene(task, default_model_spec(folder, bundle))
    if is_learned_object(spec):
        try:
            return model_scene(task, str(learned_specialist(spec)))
        except ModelError:  # resolve_method says what is wrong
            return None
    if _is_weights(spec):
        try:
            from tactile_learn.checkpoints import load_weights, weights_scene

            return weights_scene(load_weights(spec))
        except (ImportError, TactileError):  # resolve_method says what is wrong
            return None
    try:
        found = model_card(task, spec)
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
    if is_learned_object(spec):  # a learn-object folder stands for its specialist
        spec = str(learned_specialist(spec))
    if _is_weights(spec):
        return _torch_weights(task, spec, scene, threads)
    if is_bundle(spec):
        return bundle_method(task, spec, scene, threads)
    found = model_card(task, spec)
    if found is None:
        raise ConfigError(
            f"--method: {spec!r} is not a method of task {task!r} "
            f"(available: {', '.join(available_methods(task))}, or a path to a .onnx model)"
        )
    return onnx_method(task, *found, scene, threads)
