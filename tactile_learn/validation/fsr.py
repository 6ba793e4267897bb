"""Input checks of the FSR film: six ADC codes per frame, a calibrated film's mapped to the nominal film."""

from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np

from synth.sensors import fsr
from tactile_learn.calibration.fsr_film import to_nominal_film
from tactile_learn.validation.common import InputCheck

__all__ = ["fsr_bounds", "fsr_check", "fsr_input"]


def _nominal(config: fsr.FsrConfig, gains: np.ndarray, batch: np.ndarray) -> np.ndarray:
    return to_nominal_film(batch, config, gains)


def fsr_check(config: fsr.FsrConfig) -> InputCheck:
    """Readings (B, 6) as float32: finite, non-negative ADC codes below full scale.

    A code at the ADC's full scale means a saturated divider (the FSR law cannot reach it): the
    frame is refused. If the scene carries a film calibration (``[fsr.film] gains``), the readings
    are then mapped to the nominal film (:func:`~tactile_learn.calibration.fsr_film.to_nominal_film`).
    """
    gains = config.film.gains
    return InputCheck(
        (fsr.N_SENSORS,),
        upper=float(fsr.Readout(config.readout).full_scale),
        upper_name=f"the {config.readout.adc_bits}-bit ADC's full scale",
        extra=None if gains is None else partial(_nominal, config, np.asarray(gains)),
    )


def fsr_input(x: Any, config: fsr.FsrConfig) -> np.ndarray:
    """:func:`fsr_check` applied once (a caller checking batch after batch keeps the check)."""
    return fsr_check(config)(x)


def fsr_bounds(config: fsr.FsrConfig) -> tuple[float, float, bool] | None:
    """The streaming fast path's bounds; ``None`` for a calibrated film (its readings are mapped,
    not only checked)."""
    return fsr_check(config).bounds()
