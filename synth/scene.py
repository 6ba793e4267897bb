"""Scenes: what a simulated setup contains and which outputs are wanted.

A scene is a TOML file parsed into a frozen :class:`Scene`. The top level names the task and the
wanted outputs; one table named after the task (``[strips]``, ``[thermal]``, ``[fsr]``) holds the
sensor's own configuration, parsed into that sensor's config dataclass (see ``synth.sensors``)::

    name = "strips16"
    task = "strips"
    outputs = ["readings", "pressure", "latent"]
    noise = true

    [strips]
    n_rows = 16
    ...

Shipped scenes live in ``synth/scenes/*.toml`` and load by name; any other path loads as a file.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from synth.config import from_dict, to_dict
from synth.errors import ConfigError
from synth.sensors import TASKS, sensor_module

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = ["Scene", "available_scenes", "load_scene", "parse_scene", "scene_differences", "scene_digest"]

_TOP_KEYS = ("name", "task", "description", "outputs", "noise")


@dataclass(frozen=True)
class Scene:
    """A validated scene. ``sensor`` is the task's config dataclass (e.g. ``StripsConfig``)."""

    name: str
    task: str
    sensor: Any
    outputs: tuple[str, ...]
    noise: bool = True
    description: str = ""

    def with_noise(self, noise: bool) -> Scene:
        """The same scene with every noise source switched on or off."""
        return dataclasses.replace(self, noise=noise)

    def with_outputs(self, outputs: tuple[str, ...]) -> Scene:
        """The same scene asking for other outputs (validated against the sensor's outputs)."""
        _check_outputs(self.task, outputs)
        return dataclasses.replace(self, outputs=tuple(outputs))

    def wants(self, output: str) -> bool:
        return output in self.outputs

    def to_dict(self) -> dict[str, Any]:
        """The scene as plain data (the TOML layout), for manifests and model cards."""
        return {
            "name": self.name,
            "task": self.task,
            "description": self.description,
            "outputs": list(self.outputs),
            "noise": self.noise,
            self.task: to_dict(self.sensor),
        }

    @property
    def digest(self) -> str:
        return scene_digest(self)


def _check_outputs(task: str, outputs: Any) -> tuple[str, ...]:
    available = sensor_module(task).OUTPUTS
    if not isinstance(outputs, (list, tuple)) or not all(isinstance(o, str) for o in outputs):
        raise ConfigError(f"outputs: expected a list of names, got {outputs!r}")
    if not outputs:
        raise ConfigError(f"outputs: at least one output is needed (available: {', '.join(available)})")
    for out in outputs:
        if out not in available:
            raise ConfigError(f"outputs: unknown output {out!r} for task {task!r} (available: {', '.join(available)})")
    return tuple(outputs)


def parse_scene(data: dict[str, Any], source: str = "<scene>") -> Scene:
    """Validate a scene given as a dict (the parsed TOML). Errors name ``source`` and the key."""
    try:
        task = data.get("task")
        if task is None:
            raise ConfigError(f"task: missing (a scene names its sensor: task = one of {', '.join(TASKS)})")
        if task not in TASKS:
            raise ConfigError(f"task: {task!r} is not one of {', '.join(TASKS)}")
        unknown = sorted(set(data) - set(_TOP_KEYS) - {task})
        if unknown:
            raise ConfigError(f"{unknown[0]}: unknown key (known keys: {', '.join((*_TOP_KEYS, task))})")
        name = data.get("name", Path(source).stem)
        if not isinstance(name, str) or not name:
            raise ConfigError(f"name: expected a non-empty string, got {name!r}")
        description = data.get("description", "")
        if not isinstance(description, str):
            raise ConfigError(f"description: expected a string, got {description!r}")
        noise = data.get("noise", True)
        if not isinstance(noise, bool):
            raise ConfigError(f"noise: expected true or false, got {noise!r}")
        module = sensor_module(task)
        outputs = _check_outputs(task, data.get("outputs", list(module.DEFAULT_OUTPUTS)))
        section = data.get(task, {})
        sensor = from_dict(module.CONFIG_CLASS, section, task)
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}") from None
    return Scene(name=name, task=task, sensor=sensor, outputs=outputs, noise=noise, description=description)


def shipped_names(folder: str, package: str = "synth") -> list[str]:
    """Names of the TOML files shipped in the package folder ``<package>/<folder>``."""
    files = resources.files(package) / folder
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".toml"))


def available_scenes() -> list[str]:
    """Names of the scenes shipped with the package."""
    return shipped_names("scenes")


def read_toml(name_or_path: str | Path, folder: str, what: str, package: str = "synth") -> tuple[dict[str, Any], str]:
    """The parsed TOML of a file path, or of a shipped ``<package>/<folder>/<name>.toml``, and its name
    for error messages; ``what`` ("scene", "suite") names the kind in those messages."""
    text: str
    source = str(name_or_path)
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise ConfigError(f"{what} file {source} does not exist")
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ConfigError(f"{what} file {source} cannot be read: {exc}") from None
    else:
        shipped = resources.files(package) / folder / f"{source}.toml"
        if not shipped.is_file():
            names = ", ".join(shipped_names(folder, package))
            raise ConfigError(f"unknown {what} {source!r} (shipped {what}s: {names})")
        text = shipped.read_text(encoding="utf-8")
        source = f"{source}.toml"
    try:
        return tomllib.loads(text), source
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML: {exc}") from None


def load_scene(name_or_path: str | Path) -> Scene:
    """Load a shipped scene by name (``"strips16"``) or any scene TOML file by path."""
    data, source = read_toml(name_or_path, "scenes", "scene")
    return parse_scene(data, source)


def scene_digest(scene: Scene) -> str:
    """SHA-256 (hex, first 16 chars) of the scene's physics: everything but name and description."""
    data = scene.to_dict()
    data.pop("name")
    data.pop("description")
    blob = json.dumps(data, sort_keys=True, separators=(",", ":")).encode()
    return hashlib.sha256(blob).hexdigest()[:16]


def _flat(data: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(data, dict):
        out: dict[str, Any] = {}
        for key, value in data.items():
            out.update(_flat(value, f"{prefix}{key}."))
        return out
    return {prefix[:-1]: data}


def scene_differences(a: Scene, b: Scene, limit: int = 5) -> list[str]:
    """The physics keys where two scenes differ (what :func:`scene_digest` compares), as
    ``"key: A vs B"`` lines, at most ``limit`` of them (then how many more), for error messages."""
    flat_a, flat_b = (_flat({k: v for k, v in s.to_dict().items() if k not in ("name", "description")}) for s in (a, b))
    keys = sorted(k for k in flat_a.keys() | flat_b.keys() if flat_a.get(k, "(absent)") != flat_b.get(k, "(absent)"))
    lines = [f"{k}: {flat_a.get(k, '(absent)')!r} vs {flat_b.get(k, '(absent)')!r}" for k in keys[:limit]]
    if len(keys) > limit:
        lines.append(f"... and {len(keys) - limit} more")
    return lines
