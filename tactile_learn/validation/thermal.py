"""Input checks of the thermal fingertip: temperature windows (degC) inside the ADC's range."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from synth.errors import InputError
from tactile_learn.validation.common import as_batch

if TYPE_CHECKING:
    from synth.sensors.thermal import ThermalConfig

__all__ = ["thermal_bounds", "thermal_input", "thermal_input_shape"]


def thermal_input_shape(config: ThermalConfig) -> tuple[int, ...]:
    """``(W,)`` for a scene that reads the heated thermistor only, else ``(C, W)`` (heated first)."""
    if len(config.channels) == 1:
        return (config.window_samples,)
    return (len(config.channels), config.window_samples)


def thermal_input(x: Any, config: ThermalConfig) -> np.ndarray:
    """Windows (B, W) or (B, C, W) as float32: the shape, NaN/inf, and the ADC's range (a reading at
    either end of ``adc_range_c`` is saturated; below a range starting at 0 degC it is a negative,
    invalid reading)."""
    lo, hi = config.readout.adc_range_c
    batch = as_batch(
        x,
        thermal_input_shape(config),
        name="readings",
        allow_negative=lo < 0,
        upper=hi,
        upper_name="the ADC's top (degC)",
    )
    if batch.size and (batch <= lo).any():
        row = int(np.argwhere(batch <= lo)[0][0])
        raise InputError(f"readings: saturated reading at or below the ADC's bottom ({lo:g} degC) in frame {row}")
    return batch


def thermal_bounds(config: ThermalConfig) -> tuple[float, float, bool]:
    """``(low, high, low_strict)``: strictly inside the ADC's range passes :func:`thermal_input`."""
    lo, hi = config.readout.adc_range_c
    return float(lo), float(hi), True
