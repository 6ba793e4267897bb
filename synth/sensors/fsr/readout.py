"""The FSR400's conductance law (stage 3) and the divider + ADC readout (stage 4), each with its
inverse (see :mod:`synth.sensors.fsr`)."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy import special

from synth.sensors.fsr.config import FsrElementConfig, ReadoutConfig

__all__ = ["FsrLaw", "Readout"]


@dataclass(frozen=True)
class FsrLaw:
    """Conductance (uS) of one FSR400 against the load on its disc (N), and its inverse."""

    config: FsrElementConfig

    def shape(self, load_n: np.ndarray) -> np.ndarray:
        """Force-equivalent response ``F_sat tanh(F s((F - Fb)/w) / F_sat)`` (N), gain 1, no leak."""
        c = self.config
        f = np.maximum(np.asarray(load_n, dtype=np.float64), 0.0)
        gate = special.expit((f - c.break_force_n) / c.break_width_n)  # width > 0 (validated)
        return c.saturation_force_n * np.tanh(f * gate / c.saturation_force_n)

    def conductance_us(self, load_n: np.ndarray, gain: np.ndarray | float = 1.0) -> np.ndarray:
        """Conductance (uS) for loads (N) and part gains (broadcast)."""
        c = self.config
        return c.leak_conductance_us + np.asarray(gain) * c.conductance_us_per_n * self.shape(load_n)

    @functools.cached_property
    def _inverse_table(self) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        lo = max(c.break_force_n - 12.0 * c.break_width_n, 1e-6)
        loads = np.concatenate(
            [np.linspace(0.0, lo, 64, endpoint=False), np.geomspace(lo, 50.0 * c.saturation_force_n, 4000)]
        )
        shape = self.shape(loads)
        # shape is strictly increasing above ~0 (derivative > 0); keep it strictly increasing for interp
        keep = np.concatenate([[True], np.diff(shape) > 1e-300])
        return shape[keep], loads[keep]

    def load_from_shape(self, shape: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`shape` (N); responses at or above saturation map to the table's end."""
        s_tab, f_tab = self._inverse_table
        return np.interp(np.asarray(shape, dtype=np.float64), s_tab, f_tab)

    def load_from_conductance(self, conductance_us: np.ndarray, gain: np.ndarray | float = 1.0) -> np.ndarray:
        """Load (N) from conductance (uS) and part gain; at or below the leak gives 0."""
        c = self.config
        excess = np.maximum(np.asarray(conductance_us, dtype=np.float64) - c.leak_conductance_us, 0.0)
        # gain > 0 (validated, >= 0.05); conductance_us_per_n > 0 (validated)
        shape = excess / (np.asarray(gain) * c.conductance_us_per_n)
        return self.load_from_shape(shape)


@dataclass(frozen=True)
class Readout:
    """Voltage divider and ADC: conductance (uS) <-> ADC code. Noise is a separate argument."""

    config: ReadoutConfig

    @property
    def full_scale(self) -> int:
        """Largest ADC code."""
        return int(2**self.config.adc_bits - 1)

    def fraction(self, conductance_us: np.ndarray) -> np.ndarray:
        """Divider output as a fraction of the supply, ``G R / (1 + G R)``, in [0, 1)."""
        gr = np.maximum(np.asarray(conductance_us, dtype=np.float64), 0.0) * self.config.divider_kohm * 1e-3
        return gr / (1.0 + gr)  # 1 + gr >= 1

    def codes(self, conductance_us: np.ndarray, noise: np.ndarray | None = None, quantise: bool = True) -> np.ndarray:
        """ADC codes (float64) for conductances; ``noise`` (same shape, in LSB) is added before quantising."""
        levels = 2**self.config.adc_bits
        analog = self.fraction(conductance_us) * levels
        if noise is not None:
            analog = analog + noise
        if quantise:
            return np.clip(np.floor(analog), 0.0, levels - 1.0)
        return np.clip(analog - 0.5, 0.0, levels - 1.0)

    def conductance_us(self, codes: np.ndarray) -> np.ndarray:
        """Inverse readout: code -> conductance (uS), taking each code at the centre of its bin."""
        levels = 2**self.config.adc_bits
        v = (np.asarray(codes, dtype=np.float64) + 0.5) / levels
        v = np.clip(v, 0.5 / levels, 1.0 - 0.5 / levels)  # keeps 1 - v >= half a bin: no division by 0
        return v / (1.0 - v) / (self.config.divider_kohm * 1e-3)
