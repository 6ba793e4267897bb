"""The noise floor of a sensor at rest, and the gate that tells idle frames from active ones.

An *idle* frame is one whose every input value lies within the noise of the sensor with nothing
touching it. The floor is measured, not assumed: :func:`measure_idle_floor` simulates frames of the
model's own scene with every contact removed (the scene's empty-frame share set to 1: the same
noise, quantisation and part spreads as the training data) and records, per input value, the mean
and standard deviation, and as the threshold a high quantile of each frame's largest deviation in
standard deviations (``max |x - mean| / sd``). The export path writes it into the model card
(``idle`` entry); ``scripts/idle_floor.py`` adds it to an existing card.

:class:`IdleGate` applies it: one vectorised pass over the batch. A frame the gate calls idle gets
the task's empty result (:meth:`~tactile_learn.tasks.base.Task.empty_prediction`: no contact)
without running the estimator; see :class:`tactile_learn.frame_stream.FrameStream`.

The thermal task has no gate: an idle thermal window is a cooling or steady curve whose level
depends on the object's and the room's temperature, not a noise floor around one value.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from synth.errors import ConfigError, ModelError
from synth.scene import Scene, parse_scene

__all__ = ["IDLE_KEYS", "IdleGate", "idle_scene", "measure_idle_floor"]

#: per task: (stimulus table, key of the share of frames without contact) in the scene
IDLE_KEYS: dict[str, tuple[str, str]] = {
    "strips": ("stimuli", "empty_fraction"),
    "fsr": ("stimulus", "no_contact_fraction"),
    "capacitive": ("stimuli", "empty_fraction"),
}
#: share of idle frames the threshold lets through to the estimator (a false "active" costs time only)
IDLE_QUANTILE = 0.999
IDLE_SEED = 515_151  # no training, validation or benchmark set uses this seed


def idle_scene(scene: Scene) -> Scene:
    """``scene`` with every frame left empty (no contact): the sensor at rest."""
    if scene.task not in IDLE_KEYS:
        raise ConfigError(f"task {scene.task!r} has no idle gate (its idle inputs have no fixed noise floor)")
    table, key = IDLE_KEYS[scene.task]
    data = scene.to_dict()
    data[scene.task][table][key] = 1.0  # second presses and flat indenters come only with a contact
    data["name"] = f"{scene.name}_idle"
    return parse_scene(data)


def measure_idle_floor(scene: Scene, n: int = 20000, seed: int = IDLE_SEED) -> dict[str, Any]:
    """The idle floor of ``scene``'s sensor (module docstring), a JSON-ready card entry."""
    from synth.dataset import simulate_shard
    from tactile_learn.tasks import get_task

    task = get_task(scene.task)
    rest = idle_scene(scene)
    frames = task.example_inputs(simulate_shard(rest, seed, 0, n), rest)
    x = np.asarray(frames, dtype=np.float64).reshape(len(frames), -1)
    mean = x.mean(axis=0)
    # a value that never moves at rest (sd 0) counts any change as activity: 1e-9 only avoids 0/0
    sd = np.maximum(x.std(axis=0), 1e-9)
    deviation = (np.abs(x - mean) / sd).max(axis=1)
    return {
        "definition": "tactile_learn.idle: a frame is idle where max |x - mean| / sd <= threshold",
        "mean": [float(v) for v in mean],
        "sd": [float(v) for v in sd],
        "threshold": float(np.quantile(deviation, IDLE_QUANTILE)),
        "quantile": IDLE_QUANTILE,
        "measured_on": {"scene": rest.name, "frames": int(n), "seed": int(seed)},
    }


@dataclass(frozen=True)
class IdleGate:
    """Which frames are active (module docstring); float32 arithmetic, one pass over the batch."""

    mean: np.ndarray
    inv_sd: np.ndarray
    threshold: float

    @classmethod
    def from_floor(cls, floor: dict[str, Any], n_features: int, source: str = "idle floor") -> IdleGate:
        try:
            mean = np.asarray(floor["mean"], dtype=np.float32)
            sd = np.asarray(floor["sd"], dtype=np.float32)
            threshold = float(floor["threshold"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelError(f"{source}: the idle floor is incomplete or corrupt ({exc})") from None
        if mean.shape != (n_features,) or sd.shape != (n_features,):
            raise ModelError(f"{source}: the idle floor has {mean.size} values, the input has {n_features}")
        if not (np.isfinite(mean).all() and np.isfinite(sd).all() and (sd > 0).all() and threshold > 0):
            raise ModelError(f"{source}: the idle floor holds non-finite or non-positive values")
        return cls(mean, (1.0 / sd).astype(np.float32), threshold)

    def with_threshold(self, threshold: float) -> IdleGate:
        return dataclasses.replace(self, threshold=float(threshold))

    def active(self, x: np.ndarray) -> np.ndarray:
        """(B,) bool: frames with some value beyond the idle floor (``x``: a checked batch)."""
        # the feature count spelled out: reshape(B, -1) cannot infer it for an empty batch
        flat = x.reshape(len(x), math.prod(x.shape[1:]))
        return np.asarray((np.abs(flat - self.mean) * self.inv_sd).max(axis=1, initial=0.0) > self.threshold)
