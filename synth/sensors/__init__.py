"""Sensor models, one module per sensor kind.

Every sensor module exposes the same small surface, so scenes, the dataset writer and the CLI
treat all sensors alike:

- ``CONFIG_CLASS``: the frozen dataclass its scene table (``[strips]``, ...) parses into;
- ``OUTPUTS``: ``{name: description}`` of every output it can produce;
- ``DEFAULT_OUTPUTS``: the outputs a scene gets when it names none;
- ``make_simulator(scene) -> Simulator``: a :class:`~synth.sensors.base.Simulator` that computes
  only the outputs the scene asks for.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from synth.errors import ConfigError

#: task name -> module implementing that sensor
SENSOR_MODULES: dict[str, str] = {
    "strips": "synth.sensors.strips",
    "thermal": "synth.sensors.thermal",
    "fsr": "synth.sensors.fsr",
    "capacitive": "synth.sensors.capacitive",
    "fingertip": "synth.sensors.fingertip",
}
TASKS: tuple[str, ...] = tuple(SENSOR_MODULES)


def sensor_module(task: str) -> ModuleType:
    """The module implementing ``task``'s sensor (imported on first use)."""
    try:
        return importlib.import_module(SENSOR_MODULES[task])
    except KeyError:
        raise ConfigError(f"task: {task!r} is not one of {', '.join(TASKS)}") from None
