"""The capacitive array as a :class:`~synth.sensors.model.SensorModel`: cover -> hysteresis, tab,
crosstalk and readout -> noise -> ADC (physics in :mod:`synth.sensors.capacitive.physics`)."""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np

from synth.sensors.base import ArraySpec
from synth.sensors.capacitive.config import CapacitiveConfig
from synth.sensors.capacitive.layer import tab_load_operator
from synth.sensors.capacitive.physics import CellResponse
from synth.sensors.capacitive.stimuli import Presses
from synth.sensors.model import SensorModel

__all__ = ["CapacitiveModel", "load_noise_n", "nominal_span_v", "reading_noise_v"]


def nominal_span_v(config: CapacitiveConfig) -> float:
    """Reading change of a nominal cell (gain and stiffness 1, no crosstalk) from 0 to the full
    scale on the static curve: the span the effective bits refer to."""
    nominal = CellResponse.nominal(config)
    volts = nominal.volts_per_pf * nominal.law.capacitance_pf(np.array([0.0, config.readout.full_scale_n]))
    return float(volts[1] - volts[0])


def reading_noise_v(config: CapacitiveConfig) -> float:
    """Total reading noise s.d. (V): ``span / (2^bits sqrt 12)``, IEEE 1241's effective number of bits."""
    return nominal_span_v(config) / (2**config.readout.effective_bits * math.sqrt(12.0))


def load_noise_n(config: CapacitiveConfig) -> float:
    """The reading noise as a load (N) on an idle nominal cell: noise over the curve's slope at zero."""
    nominal = CellResponse.nominal(config)
    step = 1e-4 * config.readout.full_scale_n
    volts = nominal.volts_per_pf * nominal.law.capacitance_pf(np.array([0.0, step]))
    return reading_noise_v(config) * step / float(volts[1] - volts[0])


class CapacitiveModel(SensorModel[Presses]):
    """One device (the scene's ``[capacitive.device]``); readings ``(B, F, N, M)`` in volts.

    ``frames`` overrides the scene's frames per press (the fingertip's long episodes)."""

    def __init__(self, config: CapacitiveConfig, frames: int | None = None) -> None:
        self.config = config
        self.frames = frames or config.stimuli.frames
        self.response = CellResponse.true_device(config)

    @cached_property
    def operator(self) -> np.ndarray:
        """``(Hp Wp, N M)`` float32: the cover's pressure -> tab load map, transposed for ``field @ op``."""
        g = self.config.geometry
        return np.ascontiguousarray(tab_load_operator(g, self.config.cover.thickness_mm).T.astype(np.float32))

    @cached_property
    def noise_v(self) -> float:
        """Noise s.d. that, with the ADC's quantisation, leaves ``effective_bits`` over a nominal cell's
        span: ``span / (2^bits sqrt 12)`` in all (IEEE 1241's effective number of bits)."""
        r = self.config.readout
        total = reading_noise_v(self.config)
        # the ADC's own quantisation noise lsb / sqrt 12 counts towards the total (floored at 0: a
        # coarse ADC alone may already be worse than the stated resolution)
        return math.sqrt(max(total**2 - r.lsb_v**2 / 12.0, 0.0))

    def physics(self, stimulus: Presses) -> np.ndarray:
        """Load on every tab (N), ``(B, F, N, M)`` float64 (float32 matrix product; see the tests)."""
        field = stimulus.field_kpa
        b, f = field.shape[:2]
        g = self.config.geometry
        flat = field.reshape(b * f, -1).astype(np.float32, copy=False) @ self.operator
        return flat.astype(np.float64).reshape(b, f, g.n_rows, g.n_cols)

    def transduce(self, physical: np.ndarray, stimulus: Presses) -> np.ndarray:
        return self.response.volts(physical) + stimulus.drift_v[:, :, None, None]

    def noise(self, analog: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return analog + self.noise_v * rng.standard_normal(analog.shape)

    def adc(self, analog: np.ndarray) -> np.ndarray:
        r = self.config.readout
        return np.clip(np.round(analog / r.lsb_v), 0, 2**r.adc_bits - 1) * r.lsb_v

    def inverse_readout(self, readings: np.ndarray) -> np.ndarray:
        """Cell loads (N) of whole presses from drift-free readings, with the true device."""
        return self.response.loads(readings)

    def reading_spec(self) -> ArraySpec:
        g = self.config.geometry
        return ArraySpec((self.frames, g.n_rows, g.n_cols), "float32", "cell readings (V) of every frame of a press")
