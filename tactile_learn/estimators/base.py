"""The one estimator interface shared by classical and learned methods (scikit-learn conventions).

- ``__init__`` stores parameters only (no work, no validation beyond types);
- ``fit(X, y=None) -> self`` learns state into trailing-underscore attributes (a no-op where
  nothing is learned);
- ``predict(X) -> Y``: numpy in, numpy out, batch first, float32.

``task``, ``name``, ``kind`` and ``backend`` let the registry, ``eval`` and ``bench`` loop over all
methods without special cases.
"""

from __future__ import annotations

import inspect
from typing import Any, ClassVar, Literal

import numpy as np

__all__ = ["Estimator"]


class Estimator:
    task: ClassVar[str] = ""
    #: registry name of the method ("intersection", "strips16.onnx", ...)
    name: str = ""
    kind: Literal["classical", "learned"] = "classical"
    backend: str = "numpy"
    needs_fit: ClassVar[bool] = False

    def fit(self, X: np.ndarray, y: Any = None) -> Estimator:
        """Learn from ``X`` (and targets ``y``); the base class learns nothing."""
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def predict_checked(self, x: np.ndarray) -> np.ndarray:
        """``predict`` on a batch the task's ``check_inputs`` has already validated (float32, the
        right shape, in range): the streaming fast path (:mod:`tactile_learn.frame_stream`) calls this.
        Estimators whose ``predict`` validates its input override it to skip the second check."""
        return self.predict(x)

    def get_params(self) -> dict[str, Any]:
        """The ``__init__`` parameters, as stored on the instance."""
        names = [p for p in inspect.signature(type(self).__init__).parameters if p != "self"]
        return {n: getattr(self, n) for n in names if hasattr(self, n)}

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items() if k != "scene")
        return f"{type(self).__name__}({params})"
