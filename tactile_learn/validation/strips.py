"""Input checks of the strip array: one reading (V) per channel of the scene's layout."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from tactile_learn.validation.common import InputCheck

if TYPE_CHECKING:
    from synth.sensors.strips import StripsConfig

__all__ = ["strips_bounds", "strips_check", "strips_input"]


def strips_check(config: StripsConfig) -> InputCheck:
    """Readings ``(B, C)`` (``C = config.wire_count()``, worked out here once: it builds the layout)
    as float32: finite, non-negative, below the ADC's full scale (a saturated channel's load is
    unknown)."""
    return InputCheck(
        (config.wire_count(),), upper=float(config.readout.full_scale_v), upper_name="the ADC's full scale"
    )


def strips_input(x: Any, config: StripsConfig) -> np.ndarray:
    """:func:`strips_check` applied once (a caller checking batch after batch keeps the check)."""
    return strips_check(config)(x)


def strips_bounds(config: StripsConfig) -> tuple[float, float, bool] | None:
    """The streaming fast path's bounds (:meth:`InputCheck.bounds`)."""
    return strips_check(config).bounds()
