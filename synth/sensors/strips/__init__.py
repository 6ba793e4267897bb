"""Soft strip array (seed 003) on the sensor-model contract.

- :mod:`~synth.sensors.strips.config`: the ``[strips]`` scene table;
- :mod:`~synth.sensors.strips.layouts`: geometry, strip layers and readout channels of every layout;
- :mod:`~synth.sensors.strips.mechanics`: the cover's mechanics (pressure -> segment stress);
- :mod:`~synth.sensors.strips.physics`: piezoresistance, readout, noise and ADC (:class:`StripSensor`:
  every stage, and ``forward`` of a user's pressure field);
- :mod:`~synth.sensors.strips.stimuli`: contacts from the shape library (:class:`ContactGenerator`);
- :mod:`~synth.sensors.strips.sensor`: :class:`StripModel` (physics -> transduce -> noise -> adc).
"""

from __future__ import annotations

from synth.scene import Scene
from synth.sensors.model import ModelSimulator
from synth.sensors.strips.config import (
    DRAWN_PARAMS,
    ContactObject,
    CoverLayer,
    Holdout,
    Piezoresistive,
    StimulusKind,
    StripsConfig,
    StripStimuli,
    allowed_intervals,
    draw_except,
)
from synth.sensors.strips.config import StripReadout as ReadoutConfig
from synth.sensors.strips.layouts import LAYOUTS, StripGeometry, StripLayout
from synth.sensors.strips.mechanics import StripArray
from synth.sensors.strips.physics import Adc, GaussianNoise, PiezoLaw, StripReadout, StripSensor
from synth.sensors.strips.sensor import StripModel, StripStimulus
from synth.sensors.strips.stimuli import OUTPUTS, ContactGenerator, PressureField, StripContacts

__all__ = [
    "CONFIG_CLASS",
    "DEFAULT_OUTPUTS",
    "DRAWN_PARAMS",
    "LAYOUTS",
    "OUTPUTS",
    "Adc",
    "ContactGenerator",
    "ContactObject",
    "CoverLayer",
    "GaussianNoise",
    "Holdout",
    "PiezoLaw",
    "Piezoresistive",
    "PressureField",
    "ReadoutConfig",
    "StimulusKind",
    "StripArray",
    "StripContacts",
    "StripGeometry",
    "StripLayout",
    "StripModel",
    "StripReadout",
    "StripSensor",
    "StripSimulator",
    "StripStimuli",
    "StripStimulus",
    "StripsConfig",
    "allowed_intervals",
    "draw_except",
    "make_simulator",
    "sensor_model",
]

CONFIG_CLASS = StripsConfig
DEFAULT_OUTPUTS = ("readings", "pressure", "latent")


class StripSimulator(ModelSimulator):
    """A scene's simulator: the generic draw -> forward loop over :class:`StripModel` and
    :class:`ContactGenerator`; ``sensor`` is the model's :class:`StripSensor` (every stage)."""

    def __init__(self, scene: Scene) -> None:
        config: StripsConfig = scene.sensor
        self.strip_model = StripModel(config)
        rasterize = any(scene.wants(o) for o in ("readings", "pressure", "field"))
        generator = ContactGenerator(config, self.strip_model, rasterize)
        super().__init__(self.strip_model, generator, scene.outputs, scene.noise)
        self.scene = scene
        self.config = config

    @property
    def sensor(self) -> StripSensor:
        return self.strip_model.sensor


def sensor_model(config: StripsConfig) -> StripModel:
    """The sensor model of a ``[strips]`` table, its lattice padded for the scene's contacts (the
    datasets' model); ``StripModel(config, pad=0)`` has the operators of ``StripSensor(config)``."""
    return StripModel(config)


def make_simulator(scene: Scene) -> StripSimulator:
    return StripSimulator(scene)
