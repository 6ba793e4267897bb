"""Heated thermal fingertip (seed 001) on the sensor-model contract.

- :mod:`~synth.sensors.thermal.config`: the ``[thermal]`` scene table;
- :mod:`~synth.sensors.thermal.physics`: the analytic contact solution (the physics, in its docstring);
- :mod:`~synth.sensors.thermal.fast`: the same record computed only where it needs to be;
- :mod:`~synth.sensors.thermal.dynamics`, :mod:`~synth.sensors.thermal.touch`: real sensors'
  lagging, controlled channels and the passive thermistor;
- :mod:`~synth.sensors.thermal.readout`: thermistor noise and ADC;
- :mod:`~synth.sensors.thermal.stimuli`: touches (:class:`TouchGenerator`);
- :mod:`~synth.sensors.thermal.subset`: touches of which only some pixels are read (training);
- :mod:`~synth.sensors.thermal.sensor`: :class:`ThermalModel` (physics -> transduce -> noise -> adc)
  and :class:`PassiveModel`.
"""

from __future__ import annotations

from synth.errors import ConfigError
from synth.scene import Scene
from synth.sensors.model import ModelSimulator, SensorModel
from synth.sensors.thermal.config import (
    ContactConfig,
    ObjectClass,
    ObjectsConfig,
    PassiveConfig,
    ReadoutConfig,
    SensorConfig,
    ThermalConfig,
)
from synth.sensors.thermal.physics import (
    ContactModel,
    contact_excess,
    phi,
    recovery_excess,
    spreading_conductance,
    touch_excess,
)
from synth.sensors.thermal.readout import Readout
from synth.sensors.thermal.sensor import PassiveModel, ThermalModel
from synth.sensors.thermal.stimuli import OUTPUTS, Touches, TouchGenerator
from synth.sensors.thermal.subset import PixelSubset, PixelSubsetSimulator

__all__ = [
    "CONFIG_CLASS",
    "DEFAULT_OUTPUTS",
    "OUTPUTS",
    "ContactConfig",
    "ContactModel",
    "ObjectClass",
    "ObjectsConfig",
    "PassiveConfig",
    "PassiveModel",
    "PixelSubset",
    "PixelSubsetSimulator",
    "Readout",
    "ReadoutConfig",
    "SensorConfig",
    "ThermalConfig",
    "ThermalModel",
    "ThermalSimulator",
    "TouchGenerator",
    "Touches",
    "contact_excess",
    "make_simulator",
    "phi",
    "recovery_excess",
    "sensor_model",
    "spreading_conductance",
    "touch_excess",
]

CONFIG_CLASS = ThermalConfig
DEFAULT_OUTPUTS = ("readings", "latent")


class ThermalSimulator(ModelSimulator):
    """A scene's simulator: the generic draw -> forward loop over :class:`ThermalModel` (and the
    :class:`PassiveModel` channel) and :class:`TouchGenerator`; ``draw`` and ``clean_readings``
    are the generator's and the model's physics, for tests comparing the paths."""

    def __init__(self, scene: Scene, reference: bool = False) -> None:
        config: ThermalConfig = scene.sensor
        if scene.wants("passive") and not config.passive.enabled:
            raise ConfigError("outputs: 'passive' needs [thermal.passive] enabled = true")
        self.thermal_model = ThermalModel(config, reference)
        channels: dict[str, SensorModel[Touches]] = {}
        if config.passive.enabled:
            channels["passive"] = PassiveModel(self.thermal_model)
        self.touches = TouchGenerator(config)
        super().__init__(self.thermal_model, self.touches, scene.outputs, scene.noise, channels)
        self.scene = scene
        self.config = config
        self.reference = reference
        self.readout = self.thermal_model.readout
        self.time_s = self.thermal_model.time_s
        self.materials = config.material_list
        self.draw = self.touches.draw
        self.clean_readings = self.thermal_model.physics


def sensor_model(config: ThermalConfig) -> ThermalModel:
    """The sensor model of a ``[thermal]`` table (its heated channel)."""
    return ThermalModel(config)


def make_simulator(
    scene: Scene, reference: bool = False, pixels: int | None = None
) -> ThermalSimulator | PixelSubsetSimulator:
    """The scene's simulator; ``reference``: the whole-record path (see :class:`ThermalModel`);
    ``pixels``: read only that many random pixels of every touch
    (:mod:`~synth.sensors.thermal.subset`: what training reads, a fraction of the work)."""
    if pixels is None:
        return ThermalSimulator(scene, reference)
    if reference:
        raise ConfigError("pixels: a pixel subset runs on the fast path only (reference=False)")
    return PixelSubsetSimulator(scene, pixels)
