"""Estimators: classical (numpy/scipy) and learned (ONNX or torch), all with one interface."""

from tactile_learn.estimators.base import Estimator

__all__ = ["Estimator"]
