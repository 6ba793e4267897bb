"""Sensor models, one module per sensor kind.

Every sensor module exposes the same small surface, so scenes, the dataset writer and the CLI
treat all sensors alike:

- ``CONFIG_CLASS``: the frozen dataclass its scene table (``[strips]``, ...) parses into;
- ``OUTPUTS``: ``{name: description}`` of every output it can produce;
- ``DEFAULT_OUTPUTS``: the outputs a scene gets when it names none;
- ``make_simulator(scene) -> Simulator``: a :class:`~synth.sensors.base.Simulator` that computes
  only the outputs the scene asks for (the generic draw -> forward loop of
  :class:`~synth.sensors.model.ModelSimulator` over the sensor's model and stimulus generator);
- ``sensor_model(config) -> SensorModel``: the sensor's forward operator
  (:mod:`synth.sensors.model`); :func:`sensor_model` gives a scene's in one call.
"""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import TYPE_CHECKING, Any

from synth.errors import ConfigError

if TYPE_CHECKING:
    from synth.scene import Scene
    from synth.sensors.model import SensorModel

#: task name -> module implementing that sensor
SENSOR_MODULES: dict[str, str] = {
    "strips": "synth.sensors.strips",
    "thermal": "synth.sensors.thermal",
    "fsr": "synth.sensors.fsr",
    "capacitive": "synth.sensors.capacitive",
    "fingertip": "synth.sensors.fingertip",
}
TASKS: tuple[str, ...] = tuple(SENSOR_MODULES)

__all__ = ["SENSOR_MODULES", "TASKS", "sensor_model", "sensor_module"]


def sensor_module(task: str) -> ModuleType:
    """The module implementing ``task``'s sensor (imported on first use)."""
    try:
        return importlib.import_module(SENSOR_MODULES[task])
    except KeyError:
        raise ConfigError(f"task: {task!r} is not one of {', '.join(TASKS)}") from None


def sensor_model(scene: Scene) -> SensorModel[Any]:
    """The scene's sensor model (its forward operator: ``physics``, ``transduce``, ``noise``,
    ``adc``, ``forward``, ``inverse_readout``), e.g. for an estimator to push its estimates through."""
    module = sensor_module(scene.task)
    factory = getattr(module, "sensor_model", None)
    if factory is None:
        raise ConfigError(f"task: {scene.task!r} has no single sensor model (it combines several)")
    model: SensorModel[Any] = factory(scene.sensor)
    return model
