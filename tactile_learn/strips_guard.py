"""A learned strip model that says when its answer does not explain the readings.

Every general strip model (architecture 2) is exported with a second output, ``residual_rel``: its
map pushed back through the sensor's forward model and compared with the measured readings
(``tactile_learn.strips_consistency``; computed inside the ONNX graph, a few microseconds). Frames
whose residual is above the model card's ``consistency.flag_threshold`` are *flagged*: the map does
not explain what was measured, typically because the frame is unlike anything the model was trained
on (more contacts than it has seen, a damaged or drifted strip, another sensor).

The documented fallback for a flagged frame is a classical estimate (default: the intersection
rule, which assumes nothing about shapes and spreads mass over every candidate crossing rather
than inventing a pairing). :class:`CheckedStripModel` returns the learned map where the frame is
not flagged and the fallback's map where it is, with the residuals and flags beside them::

    from tactile_learn.strips_guard import CheckedStripModel
    model = CheckedStripModel("models/strips16.onnx")
    out = model.check(readings)        # pressure, learned, residual_rel, flagged
    maps = model.predict(readings)     # = out["pressure"]

The threshold is calibrated when the model is shipped: a high quantile of the residuals of the
model's own held-out frames (the card records which, and the measured flag rates).
"""

from __future__ import annotations

from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from synth.errors import ModelError
from synth.scene import Scene
from tactile_learn.estimators.base import Estimator
from tactile_learn.runtime import OnnxEstimator

__all__ = ["DEFAULT_FALLBACK", "CheckedStripModel", "calibrate_threshold"]

DEFAULT_FALLBACK = "intersection"
#: quantile of in-distribution residuals that sets the flag threshold (about 1 % false flags)
THRESHOLD_QUANTILE = 0.99


def calibrate_threshold(residuals: np.ndarray, quantile: float = THRESHOLD_QUANTILE) -> float:
    """The flag threshold: ``quantile`` of the residuals of in-distribution frames."""
    values = np.asarray(residuals, dtype=np.float64)
    values = values[np.isfinite(values)]
    if values.size == 0:
        raise ModelError("no residuals to calibrate the flag threshold on")
    return float(np.quantile(values, quantile))


class CheckedStripModel(Estimator):
    """A general strip model's maps, residuals and out-of-distribution flags, with the fallback."""

    task = "strips"
    kind = "learned"
    backend = "onnxruntime"

    def __init__(
        self,
        model: str | Path | OnnxEstimator,
        fallback: str | Estimator | None = DEFAULT_FALLBACK,
        threshold: float | None = None,
        threads: int = 1,
        scene: Scene | None = None,
    ) -> None:
        self.model = model if isinstance(model, OnnxEstimator) else OnnxEstimator(model, threads=threads, scene=scene)
        self.fallback = fallback
        self.threshold = threshold
        self.name = f"{Path(str(self.model.path)).stem}+check"

    @property
    def scene_(self) -> Scene:
        return self.model.scene_

    @cached_property
    def threshold_(self) -> float:
        if self.threshold is not None:
            return float(self.threshold)
        names = [o["name"] for o in self.model.card_["outputs"]]
        consistency = self.model.card_.get("consistency") or {}
        if "residual_rel" not in names or "flag_threshold" not in consistency:
            raise ModelError(
                f"{self.model.path}: the model has no readings residual and flag threshold "
                f"(a general strip model exported since architecture 2 has both)"
            )
        return float(consistency["flag_threshold"])

    @cached_property
    def fallback_(self) -> Estimator | None:
        if self.fallback is None or isinstance(self.fallback, Estimator):
            return self.fallback
        from tactile_learn.methods import resolve_method

        return resolve_method("strips", self.fallback, self.scene_)

    def fit(self, X: np.ndarray, y: Any = None) -> CheckedStripModel:
        return self

    def check(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """``pressure`` (the fallback's map on flagged frames), ``learned`` (the model's map),
        ``residual_rel`` and ``flagged`` (B,) of readings ``X`` (B, N+M)."""
        threshold = self.threshold_
        outputs = self.model.predict_all(X)
        learned = outputs["pressure"]
        residual = outputs["residual_rel"]
        flagged = residual > threshold
        pressure = learned
        fallback = self.fallback_
        if fallback is not None and flagged.any():
            pressure = learned.copy()
            pressure[flagged] = fallback.predict(np.asarray(X)[flagged])
        return {"pressure": pressure, "learned": learned, "residual_rel": residual, "flagged": flagged}

    def predict(self, X: np.ndarray) -> np.ndarray:
        return self.check(X)["pressure"]
