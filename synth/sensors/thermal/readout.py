"""The thermistors' noise and ADC, apart from the physics so tests can switch them off."""

from __future__ import annotations

import numpy as np

from synth.sensors.thermal.config import ReadoutConfig

__all__ = ["Readout"]


class Readout:
    """Thermistor noise and ADC: separate from the physics so tests can switch them off."""

    def __init__(self, config: ReadoutConfig) -> None:
        self.config = config

    def noise(self, clean: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        out = rng.standard_normal(clean.shape)
        out *= self.config.noise_k  # in place: the values of clean + noise_k * z, one temporary less
        out += clean
        return out

    def adc(self, temperature: np.ndarray) -> np.ndarray:
        lo, hi = self.config.adc_range_c
        step = self.config.adc_step_k
        if step <= 0:
            return np.clip(temperature, lo, hi)
        out = temperature / step
        np.round(out, out=out)
        out *= step
        return np.clip(out, lo, hi, out=out)

    def __call__(self, clean: np.ndarray, rng: np.random.Generator, noise: bool = True) -> np.ndarray:
        """Noisy, quantised readings (``noise=False``: the clean curve, unchanged)."""
        if not noise:
            return clean
        return self.adc(self.noise(clean, rng))
