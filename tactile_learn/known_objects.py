"""Known objects: a strip sensor that meets a fixed set of objects answers each of them with its own specialist.

A strip network of the default's size, fine-tuned on one object, beats the paper's rule on that object by far
more than any general model does on unseen ones (docs/strips.md: +0.144 in r over round 12's twelve objects,
none below), and the readings say which known object pressed. A *known-objects bundle* puts this to use
without touching the default for anything else: a router (a small numpy MLP on the readings, like
:mod:`tactile_learn.prior_route`'s) gives each frame probabilities over the known objects and one more class,
*other* (objects it was shown that are not known); a frame goes to the specialist of its most probable known
object when that probability exceeds the bundle's ``accept``, and every other frame to the default model.

The bundle is a folder: ``bundle.json`` (this module's format), the router's ``.npz`` (checked by SHA-256)
and one ``.onnx`` model with its card per object. ``tactile-learn objects`` builds one
(:mod:`tactile_learn.train_known_objects`, needs torch); this module runs it with numpy and onnxruntime. Pass
the bundle's ``bundle.json`` wherever a method is named (``eval --method DIR/bundle.json``) or build
:class:`KnownObjects` directly.

``bundle.json``::

    {"format": 1, "kind": "known_objects", "task": "strips", "default": "strips16",
     "objects": {"bobby_pin": "bobby_pin.onnx", ...}, "router": "router.npz", "router_sha256": "...",
     "offset": 0.3, "share_scale": 16.0, "accept": 0.94, "validation": {...}, "command": "..."}

``default`` is a shipped model's name or a path relative to the bundle; the objects' models are paths
relative to it. The router's classes are the objects in the order listed, then *other*.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from synth.errors import ConfigError, ModelError
from synth.scene import Scene
from tactile_learn.estimators.base import Estimator
from tactile_learn.prior_route import ReadingsMlp, load_router_arrays

__all__ = ["BUNDLE_FILE", "BUNDLE_KIND", "KnownObjects", "ObjectRouter", "choose", "is_bundle", "read_bundle"]

BUNDLE_FILE = "bundle.json"
BUNDLE_KIND = "known_objects"
_FORMAT = 1
#: the tasks whose readings the router's features describe (loads above an offset, shares of their total)
_TASKS = ("strips",)
#: the name :meth:`KnownObjects.route` gives frames the default answers
DEFAULT = "default"


class ObjectRouter(ReadingsMlp):
    """The router of a known-objects bundle: probabilities over the known objects and *other*."""

    def __init__(
        self, arrays: dict[str, np.ndarray], offset: float, share_scale: float, objects: tuple[str, ...]
    ) -> None:
        super().__init__(arrays, offset, share_scale)
        self.objects = objects

    def probabilities(self, readings: np.ndarray) -> np.ndarray:
        """(B, objects + 1) float32 softmax of the logits (the last column: *other*); a frame with a NaN or
        infinite reading gets NaN probabilities."""
        logits = self.logits(readings)
        with np.errstate(invalid="ignore", over="ignore"):
            # shifted by the row's largest logit: exp never overflows, and the largest term is 1
            e = np.exp(logits - logits.max(axis=1, keepdims=True))
            return e / e.sum(axis=1, keepdims=True)

    def choose(self, readings: np.ndarray, accept: float) -> np.ndarray:
        """(B,) int64: the index of the most probable known object where its probability exceeds ``accept``,
        else ``len(objects)`` (the default model). *other* is never chosen; NaN probabilities never exceed."""
        return choose(self.probabilities(readings), len(self.objects), accept)

    def choose_frame(self, frame: np.ndarray, accept: float) -> int:
        """:meth:`choose` of one frame (1, n): the same network in fewer numpy calls (the frame's scalars as
        Python floats, no softmax: the best known object's probability exceeds ``accept`` exactly when the
        sum of ``exp(z - z_best)`` over all logits is below ``1 / accept``)."""
        known = len(self.objects)
        above = np.maximum(frame[0] - self._offset32, np.float32(0.0))
        total = float(above.sum())
        if not total < math.inf:  # a NaN or infinite reading: to the default, whose input check refuses it
            return known
        h = above @ self.load_weights
        h *= self.share_scale / (total if total > 1e-6 else 1e-6)
        h += self.log_weights * math.log(total if total > 1e-4 else 1e-4) + self.bias0
        np.maximum(h, 0.0, out=h)
        h = h @ self.w1t
        h += self.b1
        np.maximum(h, 0.0, out=h)
        z = h @ self.w2t
        z += self.b2s
        best = int(z[:known].argmax())
        z -= z[best]
        # other's logit may lie far above the best known one: capped at 80 (exp(80) ~ 5.5e34, finite in
        # float32), a sum that large says "not routed" for any accept >= 0.5 as the uncapped one would
        np.minimum(z, np.float32(80.0), out=z)
        return best if float(np.exp(z).sum()) * accept < 1.0 else known


def choose(prob: np.ndarray, known: int, accept: float) -> np.ndarray:
    """(B,) int64 from probabilities (B, >= known): per frame the most probable of the first ``known`` classes
    where its probability exceeds ``accept``, else ``known``. Later columns (*other*) are never chosen."""
    best = prob[:, :known].argmax(axis=1)
    with np.errstate(invalid="ignore"):
        confident = prob[np.arange(len(prob)), best] > accept
    return np.where(confident, best, known).astype(np.int64)


def is_bundle(spec: str) -> bool:
    """Whether ``spec`` names a known-objects bundle (its ``bundle.json``, or the folder holding one)."""
    path = Path(spec)
    return (path.name == BUNDLE_FILE and path.is_file()) or (path.is_dir() and (path / BUNDLE_FILE).is_file())


def read_bundle(spec: str | Path) -> tuple[Path, dict[str, Any]]:
    """The bundle's folder and its ``bundle.json``, checked for every field :class:`KnownObjects` reads."""
    path = Path(spec)
    if path.is_dir():
        path = path / BUNDLE_FILE
    if not path.is_file():
        raise ModelError(f"{path}: known-objects bundle not found")
    try:
        bundle = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ModelError(f"{path}: cannot read the bundle ({exc})") from None
    if not isinstance(bundle, dict) or bundle.get("kind") != BUNDLE_KIND:
        raise ModelError(f"{path}: not a known-objects bundle (its kind must be {BUNDLE_KIND!r})")
    if bundle.get("format") != _FORMAT:
        raise ModelError(f"{path}: bundle format {bundle.get('format')!r}, this version reads {_FORMAT}")
    fields = ("task", "default", "objects", "router", "router_sha256", "offset", "share_scale", "accept")
    missing = [f for f in fields if f not in bundle]
    if missing:
        raise ModelError(f"{path}: the bundle lacks {', '.join(missing)}")
    if bundle["task"] not in _TASKS:
        raise ModelError(f"{path}: known-objects bundles route {', '.join(_TASKS)} readings, not {bundle['task']!r}")
    objects = bundle["objects"]
    if not isinstance(objects, dict) or not objects or not all(isinstance(v, str) for v in objects.values()):
        raise ModelError(f"{path}: the bundle's objects must map each object's name to its model file")
    if DEFAULT in objects:
        raise ModelError(f"{path}: {DEFAULT!r} cannot name an object (it names the default model's frames)")
    numbers = [bundle[k] for k in ("offset", "share_scale", "accept")]
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in numbers):
        raise ModelError(f"{path}: the bundle's offset, share_scale and accept must be finite numbers")
    if not 0.5 <= bundle["accept"] < 1.0:
        raise ModelError(f"{path}: accept {bundle['accept']!r} must be a probability in [0.5, 1)")
    return path.parent, bundle


class KnownObjects(Estimator):
    """A known-objects bundle as an estimator (module docstring): numpy in and out, batch first, float32.

    ``predict`` checks the batch as the default model does (the same clear errors for bad input), routes
    each frame, and answers it with the model the router picks; ``route`` says which one that is."""

    kind = "learned"

    def __init__(self, path: str | Path, threads: int = 1, scene: Scene | None = None) -> None:
        self.path = path
        self.threads = threads
        self.scene = scene
        self.name = Path(path).parent.name if Path(path).name == BUNDLE_FILE else Path(path).name
        self.backend = "onnxruntime"

    def prepare(self) -> KnownObjects:
        """Read and check the bundle, its router and every model (each against the default's scene), once."""
        if "members_" not in self.__dict__:
            from tactile_learn.model_files import model_card, onnx_method
            from tactile_learn.runtime import OnnxEstimator, read_card
            from tactile_learn.tasks import get_task

            folder, bundle = read_bundle(self.path)
            task = str(bundle["task"])
            found = model_card(task, default_model_spec(folder, bundle))
            if found is None:
                raise ModelError(f"{folder / BUNDLE_FILE}: the default model {bundle['default']!r} is not found")
            scene = (
                self.scene
                if self.scene is not None
                else OnnxEstimator(found[0], verify=False, card=found[1]).card_scene_
            )
            default = onnx_method(task, *found, scene, self.threads)
            members = []
            for name, file in bundle["objects"].items():
                model = folder / file
                if not model.is_file():
                    raise ModelError(f"{folder / BUNDLE_FILE}: the model of object {name!r} ({model}) is not found")
                members.append(onnx_method(task, model, read_card(model), scene, self.threads))
            inputs = int(np.prod(get_task(task).input_shape(scene)))
            objects = tuple(bundle["objects"])
            arrays = load_router_arrays(
                folder / str(bundle["router"]), str(bundle["router_sha256"]), inputs, len(objects) + 1
            )
            self.task_name_ = task
            self.objects_ = objects
            self.router_ = ObjectRouter(arrays, float(bundle["offset"]), float(bundle["share_scale"]), objects)
            self.accept_ = float(bundle["accept"])
            self.input_check_ = get_task(task).input_check(scene)
            self.scene_ = scene
            self.frame_shape_ = (1, *get_task(task).input_shape(scene))
            self.members_ = [*members, default]
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        members = self.prepared_state("members_")  # a bundle not prepared fails before the input is looked at
        if type(X) is np.ndarray and X.dtype == np.float32 and X.shape == self.frame_shape_:
            # one frame: routed as it is (a NaN or infinite reading goes to the default), then the member's
            # own one-frame path checks it with the same limits (every member has this scene's check)
            return np.asarray(members[self.router_.choose_frame(X, self.accept_)].predict(X))
        return self.predict_checked(self.input_check_(X))

    def predict_checked(self, x: np.ndarray) -> np.ndarray:
        members = self.prepared_state("members_")
        choice = self.router_.choose(x, self.accept_)
        first = int(choice[0]) if len(x) else len(members) - 1
        if len(x) == 0 or (choice == first).all():
            return np.asarray(members[first].predict_checked(x))
        parts = {int(k): np.asarray(members[int(k)].predict_checked(x[choice == k])) for k in np.unique(choice)}
        some = next(iter(parts.values()))
        out = np.empty((len(x), *some.shape[1:]), dtype=some.dtype)
        for k, part in parts.items():
            out[choice == k] = part
        return out

    def route(self, X: np.ndarray) -> np.ndarray:
        """(B,) the name of the object whose specialist answers each frame, or ``"default"``."""
        self.prepared_state("members_")
        names = np.array([*self.objects_, DEFAULT])
        return names[self.router_.choose(self.input_check_(X), self.accept_)]

    @property
    def task_name(self) -> str:
        return str(self.prepared_state("task_name_"))


def default_model_spec(folder: Path, bundle: dict[str, Any]) -> str:
    """The bundle's default model as a method spec: a shipped name as it is, a ``.onnx`` path from the bundle's
    folder."""
    default = str(bundle["default"])
    return str(folder / default) if Path(default).suffix == ".onnx" else default


def bundle_method(task: str, spec: str, scene: Scene, threads: int) -> KnownObjects:
    """The bundle ``spec`` names, prepared for ``scene`` (``resolve_method``'s loader for bundles)."""
    folder, bundle = read_bundle(spec)
    if bundle["task"] != task:
        raise ConfigError(f"{folder / BUNDLE_FILE}: the bundle is for task {bundle['task']!r}, not {task!r}")
    return KnownObjects(spec, threads=threads, scene=scene).prepare()
