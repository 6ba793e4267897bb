"""Input checks shared by every estimator and the runtime.

Each check raises :class:`~synth.errors.InputError` with a message naming the array and the
problem, never returning a silently wrong answer.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from synth.errors import InputError

if TYPE_CHECKING:
    from synth.sensors.capacitive.config import CapacitiveConfig

__all__ = ["as_batch", "capacitive_input"]


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


def capacitive_input(x: Any, config: CapacitiveConfig, quantity: Literal["readings", "cell_load"]) -> np.ndarray:
    """The capacitive array's input check, float32 out.

    - ``readings``: whole presses ``(B, F, N, M)`` in volts: finite, non-negative, below the ADC's
      full scale (a saturated cell's load is unknown);
    - ``cell_load``: calibrated loads of single frames ``(B, N, M)`` in newtons (what every method's
      ``predict`` takes): finite and not below a tenth of the full scale under zero (a calibrated
      idle cell dips below zero by its noise only; more means raw or mis-scaled input).
    """
    g = config.geometry
    cells = (g.n_rows, g.n_cols)
    if quantity == "readings":
        shape = np.shape(x) if isinstance(x, np.ndarray) else np.shape(np.asarray(x, dtype=object))
        if len(shape) != 4 or tuple(shape[2:]) != cells:
            hint = " (one press of F frames: x[None])" if len(shape) == 3 and tuple(shape[1:]) == cells else ""
            raise InputError(f"readings: expected shape (B, F, {cells[0]}, {cells[1]}), got {tuple(shape)}{hint}")
        return as_batch(
            x,
            tuple(shape[1:]),
            name="readings",
            upper=config.readout.full_scale_v,
            upper_name=f"the {config.readout.adc_bits}-bit ADC's full scale",
        )
    if quantity == "cell_load":
        loads = as_batch(x, cells, name="cell_load", allow_negative=True)
        floor = -0.1 * config.readout.full_scale_n
        if loads.size and (loads < floor).any():
            row = int(np.argwhere(loads < floor)[0][0])
            raise InputError(
                f"cell_load: negative load below {floor:.3g} N in frame {row}: calibrated cell loads (N) dip below "
                "zero by their noise only (pass readings through the front end first)"
            )
        return loads
    raise ValueError(f"quantity: {quantity!r} is not 'readings' or 'cell_load'")
