"""A learned strip model that says when its answer does not explain the readings.

Every general strip model (architecture 2) is exported with two more outputs per frame, computed
inside the ONNX graph in a few microseconds (``tactile_learn.strips_consistency``):

- ``residual``: its map pushed back through the sensor's forward model and compared with the
  measured strip loads, in units of the readout noise (``residual_sigma``); a model whose graph
  ends in a consistency step (``tactile_learn.nets.strips_consistent``) reports the residual of the
  network's map before that step - the step pulls every map toward its loads, so the map before it
  is what tells a familiar frame from a strange one (the card's ``consistency.definition`` says which;
  ``eval`` reports the residual of the returned estimate for every method);
- ``balance``: the mismatch between the row strips' and the column strips' total loads, which carry
  the same pressure on a healthy sensor (a map-free check of the readings themselves).

A frame whose residual or balance is above the model card's threshold (``consistency.thresholds``)
is *flagged*: the map does not explain what was measured, or the readings are not what this sensor
produces, typically because the frame is unlike anything the model was trained on (more contacts
than it has seen, heavier presses, a drifted or damaged strip).

The documented fallback for a flagged frame is a classical estimate (default: the intersection
rule, which assumes nothing about shapes and spreads mass over every candidate crossing rather
than inventing a pairing). :class:`CheckedStripModel` returns the learned map where the frame is
not flagged and the fallback's map where it is, with the checks and flags beside them::

    from tactile_learn.strips_guard import CheckedStripModel
    model = CheckedStripModel("models/strips16.onnx").prepare()
    out = model.check(readings)        # pressure, learned, residual, balance, flagged
    maps = model.predict(readings)     # = out["pressure"]

The thresholds are calibrated when the model is exported: a high quantile of each check on the
run's validation frames (the card records it; ``scripts/strips_flagging.py`` measures the rates).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from synth.errors import ModelError
from synth.scene import Scene
from tactile_learn.estimators.base import Estimator
from tactile_learn.runtime import OnnxEstimator, card_path

__all__ = ["CHECK_OUTPUTS", "DEFAULT_FALLBACK", "CheckedStripModel", "calibrate_threshold"]

DEFAULT_FALLBACK = "intersection"
#: the exported graph's further outputs, per frame: the readings residual of its map (in noise
#: standard deviations) and the balance of its row and column totals (tactile_learn.strips_consistency)
CHECK_OUTPUTS = ("residual", "balance")
#: quantile of each check on in-distribution frames that sets its flag threshold (1-2 % false flags)
THRESHOLD_QUANTILE = 0.99


def calibrate_threshold(residuals: np.ndarray, quantile: float = THRESHOLD_QUANTILE) -> float:
    """A flag threshold: ``quantile`` of a check's values on in-distribution frames."""
    values = np.asarray(residuals, dtype=np.float64)
    values = values[np.isfinite(values)]
    if values.size == 0:
        raise ModelError("no residuals to calibrate the flag threshold on")
    return float(np.quantile(values, quantile))


class CheckedStripModel(Estimator):
    """A general strip model's maps, checks and out-of-distribution flags, with the fallback."""

    task = "strips"
    kind = "learned"

    def __init__(
        self,
        model: str | Path | OnnxEstimator,
        fallback: str | Estimator | None = DEFAULT_FALLBACK,
        thresholds: dict[str, float] | None = None,
        threads: int = 1,
        scene: Scene | None = None,
        backend: str = "onnxruntime",
    ) -> None:
        self.model = model if isinstance(model, OnnxEstimator) else OnnxEstimator(model, threads=threads, scene=scene)
        self.fallback = fallback
        self.thresholds = thresholds
        self.threads = threads
        self.scene = scene
        self.backend = backend
        self.name = f"{Path(str(self.model.path)).stem}+check"

    @property
    def scene_(self) -> Scene:
        return self.model.scene_

    def prepare(self) -> CheckedStripModel:
        """Prepare the model, read its flag thresholds and resolve the fallback, once."""
        if "fallback_" not in self.__dict__:
            self.model.prepare()
            self.thresholds_ = self._thresholds()
            self.fallback_ = self._fallback()
        return self

    def _thresholds(self) -> dict[str, float]:
        names = {o["name"] for o in self.model.card_["outputs"]}
        if not set(CHECK_OUTPUTS) <= names:
            raise ModelError(
                f"{self.model.path}: the model has no {' and '.join(CHECK_OUTPUTS)} outputs (a general strip model "
                f"exported since the shape library has them)"
            )
        if self.thresholds is not None:
            return {k: float(self.thresholds[k]) for k in CHECK_OUTPUTS}
        consistency = self.model.card_.get("consistency") or {}
        if "thresholds" not in consistency:
            raise ModelError(f"{card_path(self.model.path)}: the card has no consistency thresholds")
        return {k: float(consistency["thresholds"][k]) for k in CHECK_OUTPUTS}

    def _fallback(self) -> Estimator | None:
        if self.fallback is None:
            return None
        if isinstance(self.fallback, Estimator):
            return self.fallback.prepare()
        from tactile_learn.methods import resolve_method

        return resolve_method("strips", self.fallback, self.scene_)

    def check(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """``pressure`` (the fallback's map on flagged frames), ``learned`` (the model's map),
        ``residual``, ``balance`` and ``flagged`` (B,) of readings ``X`` (B, N+M)."""
        thresholds: dict[str, float] = self.prepared_state("thresholds_")
        outputs = self.model.predict_all(X)
        learned = outputs["pressure"]
        flagged = np.zeros(len(learned), dtype=bool)
        for name, limit in thresholds.items():
            flagged |= outputs[name] > limit
        pressure = learned
        fallback = self.fallback_
        if fallback is not None and flagged.any():
            pressure = learned.copy()
            pressure[flagged] = fallback.predict(np.asarray(X)[flagged])
        return {
            "pressure": pressure,
            "learned": learned,
            **{k: outputs[k] for k in thresholds},
            "flagged": flagged,
        }

    def predict(self, X: np.ndarray) -> np.ndarray:
        return self.check(X)["pressure"]
