"""Force-sensing resistors (FSR400) in a PDMS film (seed 002) on the sensor-model contract.

- :mod:`~synth.sensors.fsr.config`: the ``[fsr]`` scene table;
- :mod:`~synth.sensors.fsr.geometry`: the six discs and the four triangles;
- :mod:`~synth.sensors.fsr.physics`: contact mechanics and load transfer (the physics, in its docstring);
- :mod:`~synth.sensors.fsr.readout`: the FSR400's conductance law and the divider + ADC;
- :mod:`~synth.sensors.fsr.stimuli`: presses and films (:class:`PressGenerator`);
- :mod:`~synth.sensors.fsr.sensor`: :class:`FsrModel` (physics -> transduce -> noise -> adc).
"""

from __future__ import annotations

import numpy as np

from synth.scene import Scene
from synth.sensors.fsr.config import (
    N_SENSORS,
    FilmConfig,
    FsrConfig,
    FsrElementConfig,
    LayoutConfig,
    ReadoutConfig,
    StimulusConfig,
    TransferConfig,
)
from synth.sensors.fsr.geometry import TRIANGLES, barycentric, in_triangles, sensor_positions, triangle_vertices
from synth.sensors.fsr.physics import (
    FLAT_POINTS,
    Transfer,
    _transfer_cached,
    boussinesq,
    flat_sensor_loads,
    hertz_radius_mm,
    make_transfer,
    sensor_loads,
)
from synth.sensors.fsr.readout import FsrLaw, Readout
from synth.sensors.fsr.sensor import FsrModel
from synth.sensors.fsr.stimuli import FsrPresses, PressGenerator, film_gains
from synth.sensors.model import ModelSimulator

__all__ = [
    "CONFIG_CLASS",
    "DEFAULT_OUTPUTS",
    "FLAT_POINTS",
    "N_SENSORS",
    "OUTPUTS",
    "TRIANGLES",
    "FilmConfig",
    "FsrConfig",
    "FsrElementConfig",
    "FsrLaw",
    "FsrModel",
    "FsrPresses",
    "FsrSimulator",
    "LayoutConfig",
    "PressGenerator",
    "Readout",
    "ReadoutConfig",
    "StimulusConfig",
    "Transfer",
    "TransferConfig",
    "_transfer_cached",
    "barycentric",
    "boussinesq",
    "film_gains",
    "flat_sensor_loads",
    "hertz_radius_mm",
    "in_triangles",
    "make_simulator",
    "make_transfer",
    "sensor_loads",
    "sensor_model",
    "sensor_positions",
    "triangle_vertices",
]

CONFIG_CLASS = FsrConfig
OUTPUTS: dict[str, str] = {
    "readings": "readings (6,): ADC codes of the six FSR dividers (float32)",
    "truth": "xy_mm (2,) contact centre and force_n () applied force (0 = no contact)",
    "sensor_force": "sensor_force_n (6,): noise-free load on each sensor disc (N)",
    "latent": "latent_*: film id and gains, press gains, xy, force, tip radius, contact flag",
}
DEFAULT_OUTPUTS: tuple[str, ...] = ("readings", "truth", "latent")


class FsrSimulator(ModelSimulator):
    """A scene's simulator: the generic draw -> forward loop over :class:`FsrModel` and
    :class:`PressGenerator`, plus the contact-level helpers estimators use (:meth:`forward`,
    :meth:`loads_from_readings`)."""

    def __init__(self, config: FsrConfig, outputs: tuple[str, ...], noise: bool = True) -> None:
        self.fsr_model = FsrModel(config)
        super().__init__(self.fsr_model, PressGenerator(config, self.fsr_model, noise), tuple(outputs), noise)
        self.config = config
        self.outputs = tuple(outputs)
        self.law = self.fsr_model.law
        self.readout = self.fsr_model.readout

    def forward(
        self,
        xy_mm: np.ndarray,
        force_n: np.ndarray,
        tip_radius_mm: np.ndarray | float,
        gains: np.ndarray | float = 1.0,
        rng: np.random.Generator | None = None,
        quantise: bool = True,
    ) -> np.ndarray:
        """Readings (B, 6) float64 of given contacts on a film with ``gains``; ``rng`` adds ADC noise;
        ``quantise=False``: the unquantised code (``analog - 0.5``, clipped to the codes' range)."""
        force = np.asarray(force_n, dtype=np.float64).reshape(-1)
        loads = sensor_loads(self.config, xy_mm, force, np.broadcast_to(tip_radius_mm, force.shape))
        conductance = self.law.conductance_us(loads, gains)
        noise = None if rng is None else self.config.readout.noise_lsb * rng.standard_normal(loads.shape)
        return self.readout.codes(conductance, noise, quantise=quantise)

    def loads_from_readings(self, readings: np.ndarray, gains: np.ndarray | float = 1.0) -> np.ndarray:
        """Inverse readout and FSR law: disc loads (N) from ADC codes, for part ``gains``."""
        return self.law.load_from_conductance(self.readout.conductance_us(readings), gains)


def sensor_model(config: FsrConfig) -> FsrModel:
    """The sensor model of an ``[fsr]`` table."""
    return FsrModel(config)


def make_simulator(scene: Scene) -> FsrSimulator:
    """Simulator for ``scene`` (task ``fsr``): computes only the outputs the scene asks for."""
    return FsrSimulator(scene.sensor, tuple(scene.outputs), bool(scene.noise))
