"""The one estimator interface shared by classical and learned methods (scikit-learn conventions).

- ``__init__`` stores parameters only (no work, no validation beyond types); ``backend`` (what
  computes the prediction: ``"numpy"``, ``"onnxruntime-1t"``, ...) is one of them where a method
  has a choice, so a benchmark labels an estimator by constructing it, never by rewriting it;
- ``prepare() -> self`` builds everything ``predict`` reads (sensor models, lookup tables,
  onnxruntime sessions) into trailing-underscore attributes, once; it is idempotent and does not
  look at data. ``fit(X, y=None) -> self`` learns from data where a method learns, and prepares;
  for every method here that learns nothing it is ``prepare``;
- ``predict(X) -> Y`` (numpy in, numpy out, batch first) changes nothing on the estimator
  (``tests/tactile_learn/estimators/test_estimator_contract.py`` compares ``vars(est)`` before and
  after); on an estimator that is not prepared it raises :class:`NotPreparedError`, as
  scikit-learn's ``NotFittedError``. The registry (``Task.classical_methods``,
  :func:`tactile_learn.methods.resolve_method`) hands out prepared estimators;
- classifiers (:class:`Classifier`, the thermal task) give ``predict_proba(X)`` (B, K + 1)
  probabilities over the task's output labels and ``predict(X)`` the index of the most probable
  label (int64);
- ``predict_checked(x)``: the streaming fast path (:mod:`tactile_learn.frame_stream`): ``predict``
  on a batch that has already been validated (float32, the right shape, in range), skipping the
  second check.

``task``, ``name``, ``kind`` and ``backend`` let the registry, ``eval`` and ``bench`` loop over all
methods without special cases.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar, Literal, TypeVar

import numpy as np

from synth.errors import ModelError

if TYPE_CHECKING:
    from synth.scene import Scene

__all__ = ["Classifier", "Estimator", "NotPreparedError", "labels_of", "prepared"]

E = TypeVar("E", bound="Estimator")


class NotPreparedError(ModelError):
    """``predict`` was called on an estimator whose ``prepare()`` (or ``fit()``) has not run."""


class Estimator:
    task: ClassVar[str] = ""
    #: registry name of the method ("intersection", "strips16.onnx", ...)
    name: str = ""
    kind: Literal["classical", "learned"] = "classical"
    backend: str = "numpy"
    #: whether the method is a classifier (``predict_proba`` and labels from ``predict``)
    is_classifier: ClassVar[bool] = False

    def prepare(self: E) -> E:
        """Build everything ``predict`` reads, once (the base class needs nothing)."""
        return self

    def fit(self: E, X: np.ndarray | None = None, y: Any = None) -> E:
        """Learn from ``X`` (and targets ``y``) and prepare; the base class learns nothing."""
        return self.prepare()

    def predict(self, X: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def predict_checked(self, x: np.ndarray) -> np.ndarray:
        """``predict`` on a batch that has already been validated (float32, the right shape, in
        range): the streaming fast path (:mod:`tactile_learn.frame_stream`) calls this. Estimators
        whose ``predict`` validates its input override it to skip the second check."""
        return self.predict(x)

    def prepared_state(self, name: str) -> Any:
        """The prepared attribute ``name``, or a :class:`NotPreparedError` saying what to call."""
        try:
            return self.__dict__[name]
        except KeyError:
            raise NotPreparedError(
                f"{type(self).__name__}: not prepared: call .prepare() (or .fit()) once before predict "
                "(it builds the sensor model, tables or session that every predict reads)"
            ) from None

    def get_params(self) -> dict[str, Any]:
        """The ``__init__`` parameters, as stored on the instance."""
        names = [p for p in inspect.signature(type(self).__init__).parameters if p != "self"]
        return {n: getattr(self, n) for n in names if hasattr(self, n)}

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items() if k != "scene")
        return f"{type(self).__name__}({params})"


def labels_of(proba: np.ndarray) -> np.ndarray:
    """The most probable label (int64 index, B,) of probabilities (B, K)."""
    return np.asarray(proba).argmax(axis=1).astype(np.int64, copy=False)


class Classifier(Estimator):
    """A method that classifies: ``predict_proba`` gives probabilities, ``predict`` their argmax."""

    is_classifier: ClassVar[bool] = True

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def predict_proba_checked(self, x: np.ndarray) -> np.ndarray:
        """``predict_proba`` on an already validated batch (the fast path)."""
        return self.predict_proba(x)

    def predict(self, X: np.ndarray) -> np.ndarray:
        return labels_of(self.predict_proba(X))

    def predict_checked(self, x: np.ndarray) -> np.ndarray:
        return labels_of(self.predict_proba_checked(x))


def prepared(method: Callable[..., Estimator]) -> Callable[..., Estimator]:
    """A registry factory (``Task.classical_methods``): ``method(scene, **params)``, fitted
    (prepared); the class it makes is its ``estimator_class``."""

    def make(scene: Scene, **params: Any) -> Estimator:
        return method(scene, **params).fit()

    make.__name__ = make.__qualname__ = getattr(method, "__name__", "make")
    make.estimator_class = method  # type: ignore[attr-defined]
    return make
