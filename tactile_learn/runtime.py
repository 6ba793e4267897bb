"""Deployment runtime: shipped ONNX models under onnxruntime, with numpy only (no torch).

A model is a pair ``NAME.onnx`` + ``NAME.json`` (the model card). Loading checks that they belong
together (the card's SHA-256 of the ONNX file, the scene digest embedded in the ONNX metadata, the
input and output names and shapes) and refuses a corrupt, truncated or mismatched pair with a
:class:`~synth.errors.ModelError`. ``predict`` validates its input against the card's scene with the
same checks as the classical estimators (shape, dtype, NaN/inf, negative or saturated readings).
``prepare()`` loads and checks the model and opens its session, once; ``predict`` changes nothing.
``predict`` runs the graph cut down to its first output (:mod:`tactile_learn.onnx_prune`;
``predict_all`` runs the whole graph), and a float32 batch of one frame through buffers bound to
the session, checked with one reduction (:mod:`tactile_learn.onnx_one_frame`): the batch-1 cost is
the graph's, plus ~2 us and the task's finishing (FSR: its one-press check).

A card may **route** frames (:mod:`tactile_learn.prior_route`): its ``route`` block names a second
model of the same scene and outputs (``generic_model``, with its own card) and a router file
(``router``, checked by ``router_sha256``); each frame the router calls generic is answered by that
model, the others by the card's own graph, in every path (``predict``, ``predict_all``, the one-frame
and stream paths). A missing, corrupt or mismatched member fails :meth:`OnnxEstimator.prepare`.

    from tactile_learn.runtime import OnnxEstimator
    model = OnnxEstimator("models/strips16.onnx", threads=1).prepare()
    maps = model.predict(readings)          # (B, 32) V -> (B, 16, 16) kPa
"""

from __future__ import annotations

import json
from collections.abc import Callable
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from synth.errors import ConfigError, ModelError
from synth.io import sha256_file
from synth.scene import Scene, parse_scene
from tactile_learn.estimators.base import Estimator

if TYPE_CHECKING:
    from tactile_learn.onnx_one_frame import OneFrameRun
    from tactile_learn.prior_route import PriorRoute
    from tactile_learn.tasks.base import Task

__all__ = ["CARD_FORMAT", "METADATA_KEY", "OnnxEstimator", "RoutedFrameRun", "card_path", "read_card"]

CARD_FORMAT = 1
#: key of the JSON blob that export writes into the ONNX graph's metadata
METADATA_KEY = "tactile_learn"
#: onnxruntime graph optimisation levels a card may ask for (``card["graph_optimization"]``; default
#: "all"). The NCHWc layout rewrite of "all" helps large convolutions and slows the strip networks'
#: small ones at batch 1 (measured: scripts/strips_pareto.py, docs/strips.md), so their cards ask for "extended".
GRAPH_OPTIMIZATION = ("basic", "extended", "all")


def card_path(model_path: str | Path) -> Path:
    return Path(model_path).with_suffix(".json")


def read_card(model_path: str | Path) -> dict[str, Any]:
    """The model card beside ``model_path``, checked for the fields the runtime relies on."""
    path = card_path(model_path)
    if not path.is_file():
        raise ModelError(f"{path}: model card not found (every .onnx model needs its .json card beside it)")
    try:
        card: dict[str, Any] = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise ModelError(f"{path}: corrupt model card ({exc})") from None
    missing = [
        k for k in ("format", "task", "scene", "scene_digest", "inputs", "outputs", "model_sha256") if k not in card
    ]
    if missing:
        raise ModelError(f"{path}: model card lacks {', '.join(missing)}")
    if card["format"] != CARD_FORMAT:
        raise ModelError(f"{path}: model card format {card['format']!r} is not {CARD_FORMAT}")
    return card


class OnnxEstimator(Estimator):
    """A learned estimator run by onnxruntime; task-agnostic (the card names the task)."""

    kind = "learned"

    def __init__(
        self,
        path: str | Path,
        threads: int = 1,
        verify: bool = True,
        scene: Scene | None = None,
        backend: str = "onnxruntime",
        card: dict[str, Any] | None = None,
        fuse: bool = True,
        route: bool = True,
    ) -> None:
        self.path = path
        self.threads = threads
        self.verify = verify
        self.scene = scene
        self.backend = backend
        #: the card as :func:`read_card` returned it, when the caller has read it already (the method
        #: loader reads each card once); ``None``: read beside ``path``
        self.card = card
        #: run the graph with onnxruntime's fusions the exporter leaves out (:mod:`tactile_learn.onnx_fuse`:
        #: the same function in fewer nodes; the file on disk is never changed); False: the file's graph
        self.fuse = fuse
        #: follow the card's ``route`` block (module docstring); False: this card's own graph answers
        #: every frame (a routed card's library network alone, as research and graph checks need it)
        self.route = route
        self.name = Path(path).name

    def prepare(self) -> OnnxEstimator:
        """Read and check the card, the scene and the graph, and open the onnxruntime session, once:
        a corrupt or mismatched model fails here."""
        if "run_" not in self.__dict__:
            if isinstance(self.threads, bool) or not isinstance(self.threads, int) or self.threads < 1:
                # onnxruntime reads 0 as "all cores" and fails on a negative count with its own error
                raise ConfigError(f"threads: expected a positive integer, got {self.threads!r}")
            if self.scene is not None:
                self._check_compatible(self.scene)
            self.task_ = self._task()
            self.input_check_ = self.task_.input_check(self.scene_)  # the scene's limits, worked out once
            self.finish_ = self.task_.prediction_finisher(self.scene_)
            self.session_ = self._session()
            # predict reads the first output only: a graph with more outputs runs cut down to it
            # (tactile_learn.onnx_prune; the whole graph where it cannot be cut)
            self.first_output_session_ = self._first_output_session()
            self.run_ = (
                self.first_output_session_.run,
                [self.card_["outputs"][0]["name"]],
                self.card_["inputs"][0]["name"],
            )
            # a routed card: the router and the generic member (None: every frame to this graph)
            self.route_ = self._route()
            # the batch-1 path of predict: buffers bound to the session, the range checked with
            # one reduction (tactile_learn.onnx_one_frame); None where it does not apply
            self.one_frame_ = self._routed_run(self._one_frame_run(), lambda generic: generic.one_frame_)
        return self

    def _route(self) -> tuple[PriorRoute, OnnxEstimator] | None:
        """The card's ``route`` block loaded and checked (module docstring), or ``None``."""
        from tactile_learn.prior_route import PriorRoute

        spec = self.card_.get("route") if self.route else None
        if spec is None:
            return None
        where = card_path(self.path)
        fields = ("generic_model", "router", "router_sha256", "offset", "share_scale", "threshold")
        if not isinstance(spec, dict) or [k for k in fields if k not in spec]:
            raise ModelError(f"{where}: the card's route block needs {', '.join(fields)}")
        folder = Path(self.path).parent
        # the member checks readings against this model's scene (it must take its input shape and
        # outputs); its own card's scene is the one it was trained on, which may differ
        member = folder / str(spec["generic_model"])
        if not member.is_file():
            raise ModelError(f"{where}: the routed member {member} is not found")
        member_card = read_card(member)
        if "route" in member_card:  # (one level only: no chains, no loops)
            raise ModelError(f"{where}: the routed member {spec['generic_model']} routes frames itself")
        generic = OnnxEstimator(
            member, self.threads, self.verify, self.scene_, self.backend, card=member_card, fuse=self.fuse
        ).prepare()
        mine, theirs = self.card_, generic.card_
        for key in ("task", "inputs", "outputs"):
            if mine[key] != theirs[key]:
                raise ModelError(f"{where}: the routed member {spec['generic_model']} does not match this card's {key}")
        try:
            numbers = [float(spec[k]) for k in ("offset", "share_scale", "threshold")]
        except (TypeError, ValueError):
            raise ModelError(f"{where}: the route's offset, share_scale and threshold must be numbers") from None
        inputs = int(np.prod(mine["inputs"][0]["shape"][1:]))
        route = PriorRoute.load(folder / str(spec["router"]), str(spec["router_sha256"]), inputs, *numbers)
        return route, generic

    def _routed_run(self, own: Any, of_generic: Callable[[OnnxEstimator], Any]) -> Any:
        """``own`` (a one-frame run of this graph) routed with the generic member's (``of_generic``
        of it) where the card routes; ``own`` where it does not; ``None`` where either has none."""
        if self.route_ is None or own is None:
            return own
        route, generic = self.route_
        theirs = of_generic(generic)
        if theirs is None:
            return None
        return RoutedFrameRun(route, own, theirs, (1, *self.input_shape(self.scene_)))

    @property
    def is_classifier(self) -> bool:  # type: ignore[override]
        """Whether the card's task classifies (thermal): ``predict_proba`` and labels from ``predict``."""
        return str(self.card_["task"]) == "thermal"

    @cached_property
    def card_(self) -> dict[str, Any]:
        model = Path(self.path)
        if not model.is_file():
            raise ModelError(f"{model}: model file not found")
        if model.stat().st_size == 0:
            raise ModelError(f"{model}: model file is empty")
        card = self.card if self.card is not None else read_card(model)
        if self.verify and sha256_file(model) != card["model_sha256"]:
            raise ModelError(
                f"{model}: checksum differs from its card's: the file is corrupt or belongs to another card"
            )
        return card

    @cached_property
    def card_scene_(self) -> Scene:
        """The scene the model was trained on (from its card)."""
        try:
            scene = parse_scene(self.card_["scene"], str(card_path(self.path)))
        except ConfigError as exc:
            raise ModelError(f"{card_path(self.path)}: the card's scene is invalid ({exc})") from None
        if scene.digest != self.card_["scene_digest"]:
            raise ModelError(f"{card_path(self.path)}: the card's scene does not match its scene_digest")
        if scene.task != self.card_["task"]:
            raise ModelError(
                f"{card_path(self.path)}: the card's task {self.card_['task']!r} is not its scene's {scene.task!r}"
            )
        return scene

    @property
    def scene_(self) -> Scene:
        """The scene inputs are checked against: the user's (e.g. a calibrated copy of the same
        sensor, whose check maps its readings to the nominal sensor; checked against the card's
        once, in :meth:`prepare`) or else the card's."""
        return self.card_scene_ if self.scene is None else self.scene

    def _check_compatible(self, scene: Scene) -> None:
        """``scene`` must give the card scene's input shape and name the same output classes."""
        from tactile_learn.tasks import get_task

        card_scene = self.card_scene_
        if scene.task != card_scene.task or self.input_shape(scene) != self.input_shape(card_scene):
            raise ModelError(
                f"{self.path}: the model takes {card_scene.task} inputs of shape {self.input_shape(card_scene)}, "
                f"scene {scene.name!r} gives {self.input_shape(scene)}"
            )
        task = get_task(card_scene.task)
        model_labels, scene_labels = task.output_labels(card_scene), task.output_labels(scene)
        if model_labels != scene_labels:
            # same input shape but other classes (e.g. the full material library against the seed's
            # three): the outputs would be read against the wrong names, a silent wrong answer
            raise ModelError(
                f"{self.path}: the model predicts the classes of scene {card_scene.name!r} "
                f"({', '.join(model_labels)}), scene {scene.name!r} has {', '.join(scene_labels)}; "
                f"evaluate with --scene {card_scene.name} (or a calibrated copy of it)"
            )

    def input_shape(self, scene: Scene) -> tuple[int, ...]:
        from tactile_learn.tasks import get_task

        return get_task(scene.task).input_shape(scene)

    @property
    def task_name(self) -> str:
        return str(self.card_["task"])

    def _session_options(self) -> Any:
        import onnxruntime as ort

        options = ort.SessionOptions()
        options.intra_op_num_threads = self.threads
        options.inter_op_num_threads = 1
        options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        card = self.card_
        level = card.get("graph_optimization", "all")
        if level not in GRAPH_OPTIMIZATION:
            raise ModelError(f"{self.path}: graph_optimization {level!r} is not one of {', '.join(GRAPH_OPTIMIZATION)}")
        options.graph_optimization_level = getattr(ort.GraphOptimizationLevel, f"ORT_ENABLE_{level.upper()}")
        return options

    def _session(self) -> Any:
        try:
            import onnxruntime as ort
        except ImportError:
            raise ModelError("onnxruntime is not installed: pip install 'tactile-learn[runtime]'") from None
        options = self._session_options()
        card = self.card_
        try:
            session = ort.InferenceSession(
                self._fused(Path(self.path).read_bytes()), sess_options=options, providers=["CPUExecutionProvider"]
            )
        except Exception as exc:  # onnxruntime raises its own untyped errors for corrupt graphs
            raise ModelError(f"{self.path}: onnxruntime cannot load the model ({str(exc).splitlines()[0]})") from None
        meta = session.get_modelmeta().custom_metadata_map.get(METADATA_KEY)
        if meta is None:
            raise ModelError(f"{self.path}: the ONNX graph carries no tactile-learn metadata")
        try:
            embedded = json.loads(meta)
        except ValueError:
            raise ModelError(f"{self.path}: the ONNX graph's tactile-learn metadata is corrupt") from None
        if embedded.get("scene_digest") != card["scene_digest"] or embedded.get("task") != card["task"]:
            raise ModelError(
                f"{self.path}: the ONNX graph was built for a {embedded.get('task')} scene of digest "
                f"{embedded.get('scene_digest')}, its card says {card['task']} {card['scene_digest']}: the card "
                "belongs to another model or was edited"
            )
        inputs = session.get_inputs()
        outputs = session.get_outputs()
        if [i.name for i in inputs] != [i["name"] for i in card["inputs"]]:
            raise ModelError(f"{self.path}: the graph's inputs {[i.name for i in inputs]} do not match the card's")
        if [o.name for o in outputs] != [o["name"] for o in card["outputs"]]:
            raise ModelError(f"{self.path}: the graph's outputs {[o.name for o in outputs]} do not match the card's")
        if list(inputs[0].shape[1:]) != list(card["inputs"][0]["shape"][1:]):
            raise ModelError(f"{self.path}: the graph's input shape {inputs[0].shape} does not match the card's")
        return session

    def _first_output_session(self) -> Any:
        """A session of the checked graph (:meth:`_session`) cut down to its first output
        (:func:`~tactile_learn.onnx_prune.first_output_graph`), or the whole graph's session."""
        from tactile_learn.onnx_prune import first_output_graph

        pruned = first_output_graph(self.path)
        if pruned is None:
            return self.session_
        import onnxruntime as ort

        return ort.InferenceSession(
            self._fused(pruned), sess_options=self._session_options(), providers=["CPUExecutionProvider"]
        )

    def _fused(self, model: bytes) -> bytes:
        """``model`` with :func:`~tactile_learn.onnx_fuse.fused_model_bytes`' rewrites where
        :attr:`fuse` asks for them and the ``onnx`` package is installed; else as it is."""
        from tactile_learn.onnx_fuse import fused_model_bytes

        if not self.fuse:
            return model
        try:
            return fused_model_bytes(model)
        except Exception:  # no onnx package, or bytes it cannot parse: onnxruntime's own load reports those
            return model

    def predict(self, X: np.ndarray) -> np.ndarray:
        """The first output (a classifier's: the most probable label, int64; see :meth:`predict_proba`).

        A float32 batch of one frame takes the one-frame path (:mod:`tactile_learn.onnx_one_frame`:
        the same result, without the per-call set-up); anything else, and any frame it does not
        pass as plainly valid, the full check (its clear error for bad input)."""
        one = self.prepared_state("one_frame_")  # a model not prepared fails before the input is looked at
        if one is not None:
            out = one(X)
            if out is not None:
                return out.argmax(axis=1).astype(np.int64) if self.is_classifier else out
        return self.predict_checked(self._checked(X))

    def predict_checked(self, x: np.ndarray) -> np.ndarray:
        out = self.predict_proba_checked(x)
        return out.argmax(axis=1).astype(np.int64) if self.is_classifier else out

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """A classifier's probabilities over the task's output labels (B, K + 1)."""
        one = self.prepared_state("one_frame_")
        if one is not None:
            out = one(X)
            if out is not None:
                return out
        return self.predict_proba_checked(self._checked(X))

    def predict_proba_checked(self, x: np.ndarray) -> np.ndarray:
        """The graph's first output for a validated batch (for a classifier: its probabilities);
        on a routed card, each frame's from the model the router picks for it."""
        route = self.prepared_state("route_")
        if route is None:
            return self._own_proba_checked(x)
        return _by_route(route[0], x, self._own_proba_checked, route[1].predict_proba_checked, _merged)

    def _own_proba_checked(self, x: np.ndarray) -> np.ndarray:
        """:meth:`predict_proba_checked` by this card's own graph."""
        # the session's run, the first output's name (further outputs, e.g. a residual, are not
        # needed here) and the input's name, looked up once in prepare
        run, output, input_name = self.prepared_state("run_")
        if len(x) == 0:
            return self._finish(x, np.zeros((0, *self.card_["outputs"][0]["shape"][1:]), dtype=np.float32))
        return self._finish(x, np.asarray(run(output, {input_name: x})[0], dtype=np.float32))

    def frame_runner(self) -> Callable[[np.ndarray], np.ndarray] | None:
        """A function of one validated frame ``(1, *shape)`` giving what :meth:`predict_proba_checked`
        gives, through buffers bound to the session that belong to the caller
        (:class:`~tactile_learn.onnx_one_frame.OneFrameRun`): for one caller at a time:
        :class:`~tactile_learn.frame_stream.FrameStream` builds one per stream. ``None`` where the
        graph's first output has no fixed frame shape or is not float32 (then the stream calls
        :meth:`predict_proba_checked`)."""
        self.prepared_state("run_")
        run = self._one_frame_run(bounds=(0.0, float("inf"), False))  # its check is not used here
        own = None if run is None else run.run_checked
        routed = self._routed_run(own, lambda generic: generic.frame_runner())
        return routed.run_checked if isinstance(routed, RoutedFrameRun) else routed

    def one_frame_run(self) -> OneFrameRun | RoutedFrameRun | None:
        """The batch-1 path of :meth:`predict_proba_checked` with its own check and buffers
        (:class:`~tactile_learn.onnx_one_frame.OneFrameRun`, or a :class:`RoutedFrameRun` of two;
        :meth:`predict` has one, a :class:`~tactile_learn.frame_stream.FrameStream` builds another):
        ``run(frames)`` gives the graph's finished first output for a plain valid float32 batch of
        one frame, ``None`` for anything else. ``None`` where it does not apply (a calibrated film,
        whose readings are mapped; a graph whose first output is not float32 or has no fixed frame
        shape)."""
        self.prepared_state("run_")
        return self._routed_run(self._one_frame_run(), lambda generic: generic.one_frame_run())

    def _one_frame_run(self, bounds: tuple[float, float, bool] | None = None) -> OneFrameRun | None:
        """:meth:`one_frame_run`, checking frames against ``bounds`` (default: the task's)."""
        from tactile_learn.onnx_one_frame import OneFrameRun

        session = self.first_output_session_
        bounds = self.task_.fast_bounds(self.scene_) if bounds is None else bounds
        shape = self.card_["outputs"][0]["shape"][1:]
        if bounds is None or not all(isinstance(d, int) and d > 0 for d in shape):
            return None
        if session.get_outputs()[0].type != "tensor(float)" or session.get_inputs()[0].type != "tensor(float)":
            return None
        # the task's finishing from the buffers where it has one (FSR: the one-press check on
        # Python floats), else the batch finisher on a copy of the output buffer
        one_frame_finisher = getattr(self.task_, "one_frame_finisher", None)
        finisher = one_frame_finisher(self.scene_) if one_frame_finisher is not None else None
        if finisher is None:
            finish = self.finish_

            def finisher(frame: np.ndarray, result: np.ndarray) -> np.ndarray:
                return finish(frame, result.copy())  # the buffer is overwritten by the next frame

        _, output, input_name = self.run_
        return OneFrameRun(
            session, input_name, output[0], tuple(self.input_shape(self.scene_)), tuple(shape), bounds, finisher
        )

    def predict_all(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """Every output of the graph by name (the first is what :meth:`predict_proba_checked` returns;
        on a routed card, each frame's outputs from the model the router picks for it)."""
        self.prepared_state("session_")
        x = self._checked(X)
        route = self.route_
        if route is None:
            return self._own_all_checked(x)

        def merge(
            generic: np.ndarray, own: dict[str, np.ndarray], theirs: dict[str, np.ndarray]
        ) -> dict[str, np.ndarray]:
            return {name: _merged(generic, values, theirs[name]) for name, values in own.items()}

        return _by_route(route[0], x, self._own_all_checked, route[1]._own_all_checked, merge)

    def _own_all_checked(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """:meth:`predict_all` of a validated batch by this card's own graph."""
        session = self.session_
        names = [o["name"] for o in self.card_["outputs"]]
        if len(x) == 0:
            return {o["name"]: np.zeros((0, *o["shape"][1:]), dtype=np.float32) for o in self.card_["outputs"]}
        results = session.run(names, {self.card_["inputs"][0]["name"]: x})
        out = {name: np.asarray(r, dtype=np.float32) for name, r in zip(names, results, strict=True)}
        out[names[0]] = self._finish(x, out[names[0]])
        return out

    def _task(self) -> Task:
        from tactile_learn.tasks import get_task

        return get_task(self.task_name)

    def _finish(self, x: np.ndarray, result: np.ndarray) -> np.ndarray:
        return self.finish_(x, result)

    def _checked(self, X: np.ndarray) -> np.ndarray:
        return self.input_check_(X)


_Result = TypeVar("_Result")


def _by_route(
    route: PriorRoute,
    x: np.ndarray,
    own: Callable[[np.ndarray], _Result],
    generic: Callable[[np.ndarray], _Result],
    merge: Callable[[np.ndarray, _Result, _Result], _Result],
) -> _Result:
    """A validated batch's result on a routed card: ``own`` of the frames the router keeps, ``generic``
    of those it sends on, ``merge(generic_mask, own_part, generic_part)`` where it splits the batch."""
    sent = route.generic(x)
    if len(x) == 0 or not sent.any():
        return own(x)
    if sent.all():
        return generic(x)
    return merge(sent, own(x[~sent]), generic(x[sent]))


def _merged(generic: np.ndarray, own: np.ndarray, theirs: np.ndarray) -> np.ndarray:
    """One batch from its two parts: ``theirs`` in the rows ``generic`` marks, ``own`` in the others."""
    out = np.empty((len(generic), *own.shape[1:]), dtype=own.dtype)
    out[~generic], out[generic] = own, theirs
    return out


class RoutedFrameRun:
    """Two one-frame runs behind a router (module docstring): each frame to the run the router picks;
    the same contract as :class:`~tactile_learn.onnx_one_frame.OneFrameRun` (``None``: not a plain
    valid float32 frame, take the ordinary path)."""

    def __init__(self, route: PriorRoute, own: Any, generic: Any, batch_shape: tuple[int, ...]) -> None:
        self.route, self.own, self.generic, self.batch_shape = route, own, generic, batch_shape

    def __call__(self, x: Any) -> np.ndarray | None:
        if type(x) is not np.ndarray or x.dtype is not _FLOAT32 or x.shape != self.batch_shape:
            return None
        return self.generic(x) if self.route.generic_frame(x) else self.own(x)

    def run_checked(self, x: np.ndarray) -> np.ndarray:
        """One frame the caller has checked (the runs' ``run_checked``, or the runs themselves where
        they are plain functions of a checked frame)."""
        run = self.generic if self.route.generic_frame(x) else self.own
        return getattr(run, "run_checked", run)(x)


_FLOAT32 = np.dtype(np.float32)
