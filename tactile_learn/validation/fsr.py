"""Input checks of the FSR film: six ADC codes per frame, a calibrated film's mapped to the nominal film."""

from __future__ import annotations

from typing import Any

import numpy as np

from synth.sensors import fsr
from tactile_learn.calibration.fsr_film import to_nominal_film
from tactile_learn.validation.common import as_batch

__all__ = ["fsr_bounds", "fsr_input"]


def fsr_input(x: Any, config: fsr.FsrConfig) -> np.ndarray:
    """Validated float32 readings (B, 6): finite, non-negative ADC codes below full scale.

    A code at the ADC's full scale means a saturated divider (the FSR law cannot reach it): the
    frame is refused. If the scene carries a film calibration (``[fsr.film] gains``), the readings
    are then mapped to the nominal film (:func:`~tactile_learn.calibration.fsr_film.to_nominal_film`).
    """
    batch = as_batch(
        x,
        (fsr.N_SENSORS,),
        name="readings",
        upper=float(fsr.Readout(config.readout).full_scale),
        upper_name=f"the {config.readout.adc_bits}-bit ADC's full scale",
    )
    if config.film.gains is not None and len(batch):
        batch = to_nominal_film(batch, config, np.asarray(config.film.gains))
    return batch


def fsr_bounds(config: fsr.FsrConfig) -> tuple[float, float, bool] | None:
    """``(low, high, low_strict)`` within which a float32 batch of the right shape passes
    :func:`fsr_input` unchanged; ``None`` for a calibrated film (its readings are mapped, not only
    checked)."""
    if config.film.gains is not None:
        return None
    return 0.0, float(fsr.Readout(config.readout).full_scale), False
