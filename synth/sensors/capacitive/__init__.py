"""The seed fingertip's 8 x 8 capacitive pressure array (seed 001), on the sensor-model contract.

- :mod:`~synth.sensors.capacitive.config`: the ``[capacitive]`` scene table;
- :mod:`~synth.sensors.capacitive.layer`: the cover's spreading (pressure -> tab loads);
- :mod:`~synth.sensors.capacitive.physics`: hysteresis, tab, capacitance, readout (and inverses);
- :mod:`~synth.sensors.capacitive.sensor`: :class:`CapacitiveModel` (physics -> transduce -> noise -> adc);
- :mod:`~synth.sensors.capacitive.stimuli`: presses from the shape library (:class:`PressGenerator`).
"""

from __future__ import annotations

from synth.scene import Scene
from synth.sensors.capacitive.config import CapacitiveConfig
from synth.sensors.capacitive.sensor import CapacitiveModel
from synth.sensors.capacitive.stimuli import Presses, PressGenerator
from synth.sensors.model import ModelSimulator

__all__ = [
    "CONFIG_CLASS",
    "DEFAULT_OUTPUTS",
    "OUTPUTS",
    "CapacitiveConfig",
    "CapacitiveModel",
    "PressGenerator",
    "Presses",
    "make_simulator",
    "sensor_model",
]

CONFIG_CLASS = CapacitiveConfig
OUTPUTS: dict[str, str] = {
    "readings": "cell readings (V) of every frame of a press: (F, N, M)",
    "cell_load": "true load on every tab (N): (F, N, M)",
    "image": "surface force (N) and true contact mask on the fine lattice: force_image, contact_mask (F, Ns, Ms)",
    "latent": "contact list, load profile and drift of every press",
}
DEFAULT_OUTPUTS = ("readings", "cell_load", "image", "latent")


def make_simulator(scene: Scene) -> ModelSimulator:
    config: CapacitiveConfig = scene.sensor
    model = CapacitiveModel(config)
    return ModelSimulator(model, PressGenerator(config, model), scene.outputs, scene.noise)


def sensor_model(config: CapacitiveConfig) -> CapacitiveModel:
    """The sensor model of a ``[capacitive]`` table."""
    return CapacitiveModel(config)
