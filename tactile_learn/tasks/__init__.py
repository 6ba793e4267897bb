"""Task registry: ``get_task("strips")`` returns the task object that eval, train, export and
bench ask for everything task-specific."""

from __future__ import annotations

import importlib

from synth.errors import ConfigError
from tactile_learn.tasks.base import EvalData, Task

__all__ = ["TASK_NAMES", "EvalData", "Task", "get_task"]

#: task name -> "module:TaskClass"
_TASKS: dict[str, str] = {
    "strips": "tactile_learn.tasks.strips:StripsTask",
    "thermal": "tactile_learn.tasks.thermal:ThermalTask",
    "fsr": "tactile_learn.tasks.fsr:FsrTask",
    "capacitive": "tactile_learn.tasks.capacitive:CapacitiveTask",
}
TASK_NAMES: tuple[str, ...] = tuple(_TASKS)


_INSTANCES: dict[str, Task] = {}


def get_task(name: str) -> Task:
    """The task object for ``name`` (its module is imported on first use; tasks hold no state, so
    one object per task serves every caller: the runtime asks on every ``predict``)."""
    task = _INSTANCES.get(name)
    if task is None:
        try:
            module_name, class_name = _TASKS[name].split(":")
        except KeyError:
            raise ConfigError(f"--task: {name!r} is not one of {', '.join(TASK_NAMES)}") from None
        task = _INSTANCES[name] = getattr(importlib.import_module(module_name), class_name)()
    return task
