"""Input checks of the thermal fingertip: temperature windows (degC) inside the ADC's range."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from tactile_learn.validation.common import InputCheck

if TYPE_CHECKING:
    from synth.sensors.thermal import ThermalConfig

__all__ = ["thermal_bounds", "thermal_check", "thermal_input", "thermal_input_shape"]


def thermal_input_shape(config: ThermalConfig) -> tuple[int, ...]:
    """``(W,)`` for a scene that reads the heated thermistor only, else ``(C, W)`` (heated first)."""
    if len(config.channels) == 1:
        return (config.window_samples,)
    return (len(config.channels), config.window_samples)


def thermal_check(config: ThermalConfig) -> InputCheck:
    """Windows (B, W) or (B, C, W) as float32: the shape, NaN/inf, and the ADC's range (a reading at
    either end of ``adc_range_c`` is saturated; below a range starting at 0 degC it is a negative,
    invalid reading)."""
    lo, hi = config.readout.adc_range_c
    return InputCheck(
        thermal_input_shape(config),
        allow_negative=lo < 0,
        upper=float(hi),
        upper_name="the ADC's top (degC)",
        lower=float(lo),
        lower_name="the ADC's bottom",
        lower_unit=" degC",
    )


def thermal_input(x: Any, config: ThermalConfig) -> np.ndarray:
    """:func:`thermal_check` applied once (a caller checking batch after batch keeps the check)."""
    return thermal_check(config)(x)


def thermal_bounds(config: ThermalConfig) -> tuple[float, float, bool] | None:
    """The streaming fast path's bounds: strictly inside the ADC's range."""
    return thermal_check(config).bounds()
