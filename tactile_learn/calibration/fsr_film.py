"""The FSR film's calibration: part gains fitted from known presses, and readings of a calibrated
film mapped to those of the nominal film (what every FSR method reads)."""

from __future__ import annotations

import numpy as np

from synth.sensors import fsr

__all__ = ["calibrate_gains", "to_nominal_film"]


def to_nominal_film(readings: np.ndarray, config: fsr.FsrConfig, gains: np.ndarray) -> np.ndarray:
    """Readings of a film with part ``gains`` (6,) mapped to those of the nominal film (gain 1).

    Code -> conductance -> excess over the leak divided by the gain -> code (not re-quantised).
    """
    readout = fsr.Readout(config.readout)
    leak = config.element.leak_conductance_us
    conductance = readout.conductance_us(readings)
    # the excess may be slightly negative at code 0 (bin centre below the leak): kept, so that unit
    # gains are the identity; gains >= 0.05 (validated)
    excess = (conductance - leak) / np.asarray(gains, dtype=np.float64)
    return readout.codes(leak + excess, quantise=False).astype(np.float32)


def calibrate_gains(
    readings: np.ndarray,
    xy_mm: np.ndarray,
    force_n: np.ndarray,
    config: fsr.FsrConfig,
    min_load_factor: float = 3.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Part gains (6,) of one film from known presses, and the number of presses used per sensor.

    Modelled conductance excess (nominal gain, median tip radius) against measured excess, least
    squares through the origin per sensor, over presses whose modelled load on that sensor is at
    least ``min_load_factor`` times the break force (near the break the law is too steep to
    calibrate). A sensor without such a press keeps gain 1.
    """
    law = fsr.FsrLaw(config.element)
    readout = fsr.Readout(config.readout)
    tip = float(np.median(config.stimulus.tip_radii_mm))
    loads = fsr.sensor_loads(config, xy_mm, force_n, np.full(len(force_n), tip))
    model = law.conductance_us(loads, 1.0) - config.element.leak_conductance_us
    measured = readout.conductance_us(readings) - config.element.leak_conductance_us
    use = (loads >= min_load_factor * config.element.break_force_n) & (readings < readout.full_scale)
    num = np.where(use, model * measured, 0.0).sum(axis=0)
    den = np.where(use, model * model, 0.0).sum(axis=0)
    gains = np.where(den > 0, num / np.where(den > 0, den, 1.0), 1.0)  # guarded: unused sensors keep 1
    return np.clip(gains, 0.05, 20.0), use.sum(axis=0)
