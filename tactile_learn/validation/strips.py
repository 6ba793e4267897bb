"""Input checks of the strip array: one reading (V) per channel of the scene's layout."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from tactile_learn.validation.common import as_batch

if TYPE_CHECKING:
    from synth.sensors.strips import StripsConfig

__all__ = ["strips_bounds", "strips_input"]


def strips_input(x: Any, config: StripsConfig) -> np.ndarray:
    """Readings ``(B, C)`` (``C = config.wire_count()``) as float32: finite, non-negative, below the
    ADC's full scale (a saturated channel's load is unknown)."""
    return as_batch(
        x,
        (config.wire_count(),),
        name="readings",
        upper=config.readout.full_scale_v,
        upper_name="the ADC's full scale",
    )


def strips_bounds(config: StripsConfig) -> tuple[float, float, bool]:
    """``(low, high, low_strict)`` that a float32 batch of the right shape passes
    :func:`strips_input` unchanged within (the streaming fast path's two reductions)."""
    return 0.0, float(config.readout.full_scale_v), False
