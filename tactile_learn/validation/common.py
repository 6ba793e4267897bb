"""The common part of the input checks: a batch of numbers of the right shape, finite, in range.

Each check raises :class:`~synth.errors.InputError` with a message naming the array and the
problem, never returning a silently wrong answer.

:func:`as_batch` checks one array against limits given on every call. :class:`InputCheck` holds a
sensor's limits worked out once from its scene (a strip layout's channel count, an ADC's full scale:
looking them up cost more than the check itself at batch 1): an estimator builds it in ``prepare``
and calls it on every batch; its :meth:`InputCheck.bounds` let a stream check a float32 batch with
two reductions.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from synth.errors import InputError

__all__ = ["InputCheck", "as_batch"]


@dataclass(frozen=True)
class InputCheck:
    """A batch check with its limits fixed: ``check(x)`` is ``as_batch(x, shape, ...)``, then a
    sensor's own ``extra`` check or mapping (e.g. a calibrated film's readings to the nominal film).

    ``lower`` (with ``lower_name``): values at or below it are refused too (an ADC's bottom)."""

    shape: tuple[int, ...]
    name: str = "readings"
    allow_negative: bool = False
    upper: float | None = None
    upper_name: str = "the full-scale value"
    lower: float | None = None
    lower_name: str = "the lowest valid value"
    #: unit printed after the limit in the ``lower`` message (" degC")
    lower_unit: str = ""
    #: applied to the checked float32 batch (a mapping); ``None``: the check only checks
    extra: Callable[[np.ndarray], np.ndarray] | None = None

    def __call__(self, x: Any) -> np.ndarray:
        batch = as_batch(
            x,
            self.shape,
            name=self.name,
            allow_negative=self.allow_negative,
            upper=self.upper,
            upper_name=self.upper_name,
        )
        if self.lower is not None and batch.size and (batch <= self.lower).any():
            row = int(np.argwhere(batch <= self.lower)[0][0])
            raise InputError(
                f"{self.name}: saturated reading at or below {self.lower_name} ({self.lower:g}{self.lower_unit}) "
                f"in frame {row}"
            )
        return self.extra(batch) if self.extra is not None and len(batch) else batch

    def bounds(self) -> tuple[float, float, bool] | None:
        """``(low, high, low_strict)``: a float32 C-contiguous batch of the right shape whose values
        all satisfy ``low <= x < high`` (``low < x`` where ``low_strict``) passes the check unchanged
        (NaN fails both comparisons); ``None`` where the check maps its input (``extra``)."""
        if self.extra is not None:
            return None
        high = float("inf") if self.upper is None else float(self.upper)
        if self.lower is not None:
            return float(self.lower), high, True
        return (-float("inf") if self.allow_negative else 0.0), high, False


def as_batch(
    x: Any,
    feature_shape: tuple[int, ...],
    *,
    name: str = "readings",
    allow_negative: bool = False,
    upper: float | None = None,
    upper_name: str = "the full-scale value",
) -> np.ndarray:
    """Validate ``x`` as a batch of shape ``(B, *feature_shape)`` and return it as C-contiguous float32.

    Refuses non-numeric data, a wrong shape, NaN/inf, negative values (unless ``allow_negative``)
    and values at or above ``upper`` (a saturated readout). The batch may be empty (B = 0).
    """
    if type(x) is np.ndarray and x.dtype == np.float32:  # the common case: no dtype to inspect
        array = x
    else:
        try:
            array = np.asarray(x)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{name}: cannot be read as an array ({exc})") from None
        if array.dtype == object or not (np.issubdtype(array.dtype, np.number) or array.dtype == np.bool_):
            raise InputError(f"{name}: expected numbers, got dtype {array.dtype}")
        if np.issubdtype(array.dtype, np.complexfloating):
            raise InputError(f"{name}: expected real numbers, got dtype {array.dtype}")
    expected = ("B", *feature_shape)
    if array.ndim != len(expected) or tuple(array.shape[1:]) != tuple(feature_shape):
        hint = " (a single frame needs a batch axis: x[None])" if tuple(array.shape) == tuple(feature_shape) else ""
        raise InputError(f"{name}: expected shape {expected}, got {tuple(array.shape)}{hint}")
    array = np.ascontiguousarray(array, dtype=np.float32)
    if array.size:
        # two reductions decide whether anything is wrong (NaN propagates into min and max, inf is
        # an extreme); the offending frame is only looked for when something is
        low, high = float(array.min()), float(array.max())
        if not (math.isfinite(low) and math.isfinite(high)):
            row = int(np.argwhere(~np.isfinite(array))[0][0])
            raise InputError(f"{name}: contains NaN or inf (first in frame {row})")
        if not allow_negative and low < 0:
            row = int(np.argwhere(array < 0)[0][0])
            raise InputError(f"{name}: negative values are not valid readings (first in frame {row})")
        if upper is not None and high >= upper:
            row = int(np.argwhere(array >= upper)[0][0])
            raise InputError(f"{name}: saturated reading at or above {upper_name} ({upper:g}) in frame {row}")
    return array
