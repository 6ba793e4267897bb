"""Input checks of the capacitive array: whole presses of readings (V) or calibrated cell loads (N)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from synth.errors import InputError
from tactile_learn.validation.common import as_batch

if TYPE_CHECKING:
    from synth.sensors.capacitive.config import CapacitiveConfig

__all__ = ["capacitive_input"]


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
