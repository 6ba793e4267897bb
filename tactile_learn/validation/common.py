"""The common part of the input checks: a batch of numbers of the right shape, finite, in range.

Each check raises :class:`~synth.errors.InputError` with a message naming the array and the
problem, never returning a silently wrong answer.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from synth.errors import InputError

__all__ = ["as_batch"]


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
        if not (np.isfinite(low) and np.isfinite(high)):
            row = int(np.argwhere(~np.isfinite(array))[0][0])
            raise InputError(f"{name}: contains NaN or inf (first in frame {row})")
        if not allow_negative and low < 0:
            row = int(np.argwhere(array < 0)[0][0])
            raise InputError(f"{name}: negative values are not valid readings (first in frame {row})")
        if upper is not None and high >= upper:
            row = int(np.argwhere(array >= upper)[0][0])
            raise InputError(f"{name}: saturated reading at or above {upper_name} ({upper:g}) in frame {row}")
    return array
