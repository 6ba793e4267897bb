"""The thermistors' noise and ADC, apart from the physics so tests can switch them off."""

from __future__ import annotations

import numpy as np

from synth.sensors.thermal.config import ReadoutConfig

__all__ = ["Readout", "drift_ending_at_contact"]


def drift_ending_at_contact(t: np.ndarray, tau_s: float | np.ndarray) -> np.ndarray:
    """A reading-side drift of unit slope (K/s) that the contact ends, per K/s of its slope.

    ``t``: time from the contact's start (s). Before it the reading drifts as ``t``; from it on the
    drift's slope relaxes to 0 through a first-order lag ``tau_s`` (s):
    ``d(t) = tau (1 - exp(-t / tau))`` for ``t >= 0`` (the solution of ``tau d'' + d' = 0`` from a
    slope of 1 at ``t = 0``, continuous with its slope). No heat is involved: the body's temperature
    does not follow the drift, so nothing continues as net heating after the contact (what the
    calibration's default drift, a heater still settling, does)."""
    tau = np.asarray(tau_s, dtype=float)
    # clamp: exp of a non-positive argument only (t < 0 takes the other branch); tau > 0
    after = tau * -np.expm1(-np.maximum(t, 0.0) / np.maximum(tau, 1e-9))
    return np.where(t < 0.0, t, after)


class Readout:
    """Thermistor noise and ADC: separate from the physics so tests can switch them off."""

    def __init__(self, config: ReadoutConfig) -> None:
        self.config = config

    def noise(self, clean: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        out = rng.standard_normal(clean.shape)
        out *= self.config.noise_k  # in place: the values of clean + noise_k * z, one temporary less
        out += clean
        return out

    def add_noise(self, clean: np.ndarray, scratch: np.ndarray, rng: np.random.Generator) -> None:
        """:meth:`noise` in place: ``clean`` gets the noise (the same draws and the same bytes:
        ``clean + noise_k z`` is ``noise_k z + clean`` exactly), ``scratch`` (as ``clean``) takes
        the draws, so a loop over blocks allocates nothing per block."""
        rng.standard_normal(out=scratch)  # fills in C order: the stream of standard_normal(shape)
        scratch *= self.config.noise_k
        clean += scratch

    def adc(self, temperature: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Quantised and clipped readings; ``out`` (may be ``temperature`` itself) takes them."""
        lo, hi = self.config.adc_range_c
        step = self.config.adc_step_k
        if step <= 0:
            return np.clip(temperature, lo, hi, out=out)
        out = np.divide(temperature, step, out=out)
        np.round(out, out=out)
        out *= step
        return np.clip(out, lo, hi, out=out)

    def __call__(self, clean: np.ndarray, rng: np.random.Generator, noise: bool = True) -> np.ndarray:
        """Noisy, quantised readings (``noise=False``: the clean curve, unchanged)."""
        if not noise:
            return clean
        return self.adc(self.noise(clean, rng))
