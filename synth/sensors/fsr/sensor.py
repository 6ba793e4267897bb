"""The FSR film as a :class:`~synth.sensors.model.SensorModel`: contact mechanics and load transfer
-> FSR conductance and divider -> ADC input noise -> ADC (stages in :mod:`synth.sensors.fsr`)."""

from __future__ import annotations

import numpy as np

from synth.sensors.base import ArraySpec
from synth.sensors.fsr.config import N_SENSORS, FsrConfig
from synth.sensors.fsr.physics import flat_sensor_loads, sensor_loads
from synth.sensors.fsr.readout import FsrLaw, Readout
from synth.sensors.fsr.stimuli import FsrPresses
from synth.sensors.model import SensorModel

__all__ = ["FsrModel"]


class FsrModel(SensorModel[FsrPresses]):
    """One film; readings ``(B, 6)``: ADC codes of the six dividers.

    ``physics`` -> load on every disc (N); ``transduce`` -> the divider's output in LSB, ``levels G
    R_m / (1 + G R_m)`` (code ``k`` covers ``[k, k + 1)``), for the press's part gains; ``noise`` ->
    Gaussian ADC input noise of ``noise_lsb``; ``adc`` -> ``floor``, clipped to the codes. Readings
    are codes even without noise (:attr:`codes_without_noise`). ``inverse_readout`` -> disc loads of
    a nominal film (gain 1) from codes, each code at the centre of its bin.
    """

    codes_without_noise = True

    def __init__(self, config: FsrConfig) -> None:
        self.config = config
        self.law = FsrLaw(config.element)
        self.readout = Readout(config.readout)

    def physics(self, stimulus: FsrPresses) -> np.ndarray:
        """Noise-free load (N) on each disc, (B, 6) float64 (a flat indenter's, plus a second press)."""
        cfg = self.config
        loads = sensor_loads(cfg, stimulus.xy_mm, stimulus.force_n, stimulus.tip_radius_mm)
        unusual = stimulus.unusual
        if unusual is None:
            return loads
        flat = unusual["flat"]
        if flat.any():
            loads[flat] = flat_sensor_loads(
                cfg, stimulus.xy_mm[flat], stimulus.force_n[flat], unusual["flat_radius"][flat]
            )
        second = unusual["second"]
        if second.any():
            loads[second] += sensor_loads(
                cfg, unusual["second_xy"][second], unusual["second_force"][second], unusual["second_tip"][second]
            )
        return loads

    def transduce(self, physical: np.ndarray, stimulus: FsrPresses) -> np.ndarray:
        conductance = self.law.conductance_us(physical, stimulus.press_gain)
        return self.readout.fraction(conductance) * 2**self.config.readout.adc_bits

    def noise(self, analog: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return self.add_noise(analog, rng.standard_normal(analog.shape))

    def add_noise(self, analog: np.ndarray, unit: np.ndarray) -> np.ndarray:
        """``analog`` plus the ADC input noise of unit normal draws ``unit``."""
        return analog + self.config.readout.noise_lsb * unit

    def adc(self, analog: np.ndarray) -> np.ndarray:
        levels = 2**self.config.readout.adc_bits
        return np.clip(np.floor(analog), 0.0, levels - 1.0)

    def forward(self, stimulus: FsrPresses, rng: np.random.Generator | None = None) -> np.ndarray:
        """As :meth:`SensorModel.forward`; drawn frames carry their ADC noise draws (``adc_noise``,
        drawn with the stimulus), which the noise stage uses instead of fresh draws from ``rng``."""
        clean = self.transduce(self.physics(stimulus), stimulus)
        if rng is None:
            return clean
        noisy = self.noise(clean, rng) if stimulus.adc_noise is None else self.add_noise(clean, stimulus.adc_noise)
        return self.adc(noisy)

    def inverse_readout(self, readings: np.ndarray) -> np.ndarray:
        """Disc loads (N) of a nominal film from ADC codes (:meth:`FsrLaw.load_from_conductance`)."""
        return self.law.load_from_conductance(self.readout.conductance_us(readings))

    def reading_spec(self) -> ArraySpec:
        return ArraySpec((N_SENSORS,), "float32", "ADC codes of S0..S5")
