"""Streaming frames through an estimator: checks and set-up once per session, idle frames skipped.

``predict`` of every estimator is safe for any input: it validates the batch (shape, dtype, NaN/inf,
range) and looks up the task and the scene on every call. A sensor read frame by frame pays that
on every frame. :class:`FrameStream` is the fast path for that case: it resolves the task, the
scene, the input shape and the valid range once, checks each batch with two reductions (its
minimum and maximum against the range: NaN and inf fail too) and calls the estimator's
``predict_checked``. Anything unusual (another dtype or shape, a value out of range, a task whose
check does more than check) goes through the task's full ``check_inputs``, so bad input gets the
same clear :class:`~synth.errors.InputError` as ``predict`` gives. A learned model's single frames
(without a gate) go through buffers bound to the session that the stream owns
(:meth:`~tactile_learn.runtime.OnnxEstimator.one_frame_run`: the frame copied into a bound input
and range-checked there with one reduction, no per-call dicts or allocations inside onnxruntime);
a classical method's through its own single-frame path (set up in ``prepare``: see each method's
docstring).

With ``gate=True`` (or an :class:`~tactile_learn.idle.IdleGate`) the stream also skips idle frames:
frames within the sensor's noise floor at rest (the model card's ``idle`` entry; for a classical
method, measured on its scene when the stream starts) get the task's empty
result (no contact) without running the estimator; in a mixed batch only the active frames are
sent to it, and their results are exactly what the estimator gives for them.

    from tactile_learn.runtime import OnnxEstimator
    from tactile_learn.frame_stream import FrameStream

    stream = FrameStream(OnnxEstimator("models/strips16.onnx"), gate=True)
    for frame in sensor:                     # (N+M,) readings, one at a time
        pressure = stream.predict(frame[None])[0]
    stream.skipped, stream.frames            # idle frames answered without the network

``tactile-learn run`` applies the same object to a file of frames.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from synth.errors import ConfigError, ModelError
from synth.scene import Scene
from tactile_learn.estimators.base import Estimator
from tactile_learn.idle import IdleGate, measure_idle_floor
from tactile_learn.stream_one_frame import OneFrameGate
from tactile_learn.tasks import get_task

__all__ = ["FrameStream", "card_gate"]


def card_gate(estimator: Estimator, scene: Scene) -> IdleGate:
    """The idle gate of ``estimator`` on ``scene``: a learned model's from its card's ``idle``
    entry; a classical method's measured now on the scene (a second or so)."""
    from tactile_learn.runtime import OnnxEstimator

    model = getattr(estimator, "model", estimator)  # a checked strip model wraps its ONNX model
    n_features = int(np.prod(get_task(scene.task).input_shape(scene)))
    if not isinstance(model, OnnxEstimator):
        return IdleGate.from_floor(measure_idle_floor(scene, n=4000), n_features, source=scene.name)
    floor = model.card_.get("idle")
    if floor is None:
        raise ModelError(
            f"{model.path}: the model card has no idle floor; add it with "
            f"'python scripts/idle_floor.py {model.path}' (or re-export the model)"
        )
    return IdleGate.from_floor(floor, n_features, source=str(model.path))


def _task_and_scene(estimator: Estimator) -> tuple[str, Scene]:
    from tactile_learn.runtime import OnnxEstimator

    if isinstance(estimator, OnnxEstimator):
        return estimator.task_name, estimator.scene_
    scene = getattr(estimator, "scene_", None) or getattr(estimator, "scene", None)
    if not isinstance(scene, Scene):
        raise ModelError(f"{type(estimator).__name__}: a stream needs an estimator with a scene")
    return scene.task, scene


class FrameStream:
    """One estimator, fed batch after batch (often of one frame): see the module docstring.

    ``frames`` and ``skipped`` count what went through and what the gate answered itself.
    """

    def __init__(self, estimator: Estimator, gate: bool | IdleGate = False) -> None:
        self.estimator = estimator.prepare()  # the session's set-up, once (idempotent)
        task_name, self.scene = _task_and_scene(estimator)
        self.task = get_task(task_name)
        self.shape = tuple(self.task.input_shape(self.scene))
        self.bounds = self.task.fast_bounds(self.scene)
        self.gate: IdleGate | None = card_gate(estimator, self.scene) if gate is True else (gate or None)
        # a classifier's stream gives its probabilities (the task's output, as ``run`` writes it)
        fast = "predict_proba_checked" if estimator.is_classifier else "predict_checked"
        compute: Callable[[np.ndarray], np.ndarray] = getattr(estimator, fast)
        self._compute = compute
        # a learned model's single frames through an io binding owned by this stream
        # (only ungated: a gated stream sends its active frames through predict_checked, which the
        # gate's tests watch; its saving is the skipped frames)
        runner = getattr(estimator, "frame_runner", None) if self.gate is None else None
        self._compute_one: Callable[[np.ndarray], np.ndarray] | None = runner() if runner is not None else None
        # and a plain float32 frame with the check too: the range on its bit patterns in the bound
        # buffer (tactile_learn.onnx_one_frame), before any of the checks below
        run_one = getattr(estimator, "one_frame_run", None) if self.gate is None else None
        self._run_one: Callable[[Any], np.ndarray | None] | None = run_one() if run_one is not None else None
        self.frames = 0
        self.skipped = 0
        # a batch of one small frame: check and gate on Python floats (tactile_learn.stream_one_frame)
        self._one_frame = OneFrameGate.build(self.shape, self.bounds, self.gate)

    def check(self, frames: Any) -> np.ndarray:
        """``frames`` as the validated float32 batch ``predict`` would see (or an InputError)."""
        bounds = self.bounds
        if (
            bounds is not None
            and type(frames) is np.ndarray
            and frames.dtype == np.float32
            and frames.shape[1:] == self.shape
            and frames.ndim == len(self.shape) + 1
            and frames.flags.c_contiguous
            and len(frames)
        ):
            low, high, strict = bounds
            lo, hi = frames.min(), frames.max()
            if (lo > low if strict else lo >= low) and hi < high:
                return frames
        return self.task.check_inputs(frames, self.scene)  # the full check: its clear error, or a copy

    def predict(self, frames: Any) -> np.ndarray:
        """The estimator's prediction for ``frames`` (batch first); idle frames answered by the gate."""
        run_one = self._run_one
        if run_one is not None:
            out = run_one(frames)
            if out is not None:  # a plain valid frame (else the checks below: the answer or the error)
                self.frames += 1
                return out
        one = self._one_frame
        verdict = one.plain_verdict(frames) if one is not None else None
        if verdict is not None:  # a valid frame (else the full check below gives its error)
            self.frames += 1
            if verdict:
                return (self._compute_one or self._compute)(frames)
            self.skipped += 1
            return self.task.empty_prediction(1, self.scene)
        x = self.check(frames)
        n = len(x)
        self.frames += n
        if n == 1 and self._compute_one is not None:
            return self._compute_one(x)
        if self.gate is None or not n:
            return self._compute(x)
        active = self.gate.active(x)
        n_active = int(np.count_nonzero(active))
        self.skipped += n - n_active
        if n_active == n:
            return self._compute(x)
        out = self.task.empty_prediction(n, self.scene)
        if n_active:
            out[active] = self._compute(x[active])
        return out

    def run(self, frames: Any, batch: int = 1024) -> np.ndarray:
        """Predictions for a long array of frames, ``batch`` frames per call (a file of frames)."""
        if not hasattr(batch, "__index__") or batch < 1:
            raise ConfigError(f"batch: expected a positive integer, got {batch!r}")
        x = self.check(frames)
        if len(x) <= batch:
            return self.predict(x)
        return np.concatenate([self.predict(x[i : i + batch]) for i in range(0, len(x), batch)])

    @property
    def skipped_share(self) -> float:
        return self.skipped / self.frames if self.frames else 0.0
