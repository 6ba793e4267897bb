"""Evaluation suites: named families of scenes that share one sensor, for per-family results.

A suite is a TOML file (shipped ones in ``synth/suites/``, loaded by name)::

    name = "strips16_ood"
    base = "strips16"          # the scene every family starts from (its sensor, noise, outputs)
    description = "..."
    frames = 1000              # frames per family unless the caller asks for another number

    [[families]]
    name = "washer"
    description = "one M5 washer"
    [families.strips.stimuli]  # replaces the base scene's stimuli as a whole
    count = [1, 1]
    ...

A family's table is merged into the base scene's (``[families.strips.layers]`` could give a family
another cover, say), except ``stimuli``, which a family that names it replaces whole: a family's
contacts never inherit kinds or counts from the base without saying so. Every family becomes a
validated :class:`~synth.scene.Scene` named ``SUITE/FAMILY``; errors name the suite and the family.
Family ``i`` of a suite drawn with ``seed`` is simulated with ``SeedSequence(seed, spawn_key=(i,))``
(:func:`suite_frames`): the same seed gives the same frames, bit for bit.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from synth.errors import ConfigError
from synth.scene import Scene, load_scene, parse_scene, read_toml, shipped_names

__all__ = ["Family", "Suite", "available_suites", "load_suite", "parse_suite", "suite_frames"]

_TOP_KEYS = ("name", "base", "description", "frames", "families")
_FAMILY_KEYS = ("name", "description")


@dataclass(frozen=True)
class Family:
    name: str
    scene: Scene
    description: str = ""


@dataclass(frozen=True)
class Suite:
    name: str
    base: Scene
    families: tuple[Family, ...]
    frames: int = 1000
    description: str = ""

    def family(self, name: str) -> Family:
        for fam in self.families:
            if fam.name == name:
                return fam
        raise ConfigError(f"suite {self.name!r} has no family {name!r} (families: {', '.join(self.names)})")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.families)


def _merge(base: dict[str, Any], extra: dict[str, Any], replace: tuple[str, ...]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for key, value in extra.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict) and key not in replace:
            out[key] = _merge(out[key], value, replace)
        else:
            out[key] = copy.deepcopy(value)
    return out


def _text(value: Any, what: str) -> str:
    if not isinstance(value, str):
        raise ConfigError(f"{what}: expected a string, got {value!r}")
    return value


def parse_suite(data: dict[str, Any], source: str = "<suite>") -> Suite:
    """Validate a suite given as a dict (the parsed TOML)."""
    unknown = sorted(set(data) - set(_TOP_KEYS))
    if unknown:
        raise ConfigError(f"{source}: {unknown[0]}: unknown key (known keys: {', '.join(_TOP_KEYS)})")
    name = _text(data.get("name", Path(source).stem), f"{source}: name")
    base = load_scene(_text(data.get("base"), f"{source}: base"))
    frames = data.get("frames", 1000)
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
        raise ConfigError(f"{source}: frames: expected a positive integer, got {frames!r}")
    families_data = data.get("families")
    if not isinstance(families_data, list) or not families_data:
        raise ConfigError(f"{source}: families: at least one [[families]] table is needed")
    families: list[Family] = []
    base_dict = base.to_dict()
    for index, fam in enumerate(families_data):
        where = f"{source}: families[{index}]"
        if not isinstance(fam, dict):
            raise ConfigError(f"{where}: expected a table")
        fam_name = _text(fam.get("name"), f"{where}: name")
        if not fam_name or "/" in fam_name:
            raise ConfigError(f"{where}: name: {fam_name!r} must be a non-empty name without '/'")
        if fam_name in [f.name for f in families]:
            raise ConfigError(f"{where}: name: {fam_name!r} appears twice")
        unknown = sorted(set(fam) - set(_FAMILY_KEYS) - {base.task})
        if unknown:
            raise ConfigError(
                f"{where} ({fam_name}): {unknown[0]}: unknown key (a family holds name, description "
                f"and a [{base.task}] table)"
            )
        merged = _merge(base_dict, {base.task: fam.get(base.task, {})}, replace=("stimuli",))
        merged["name"] = f"{name}/{fam_name}"
        merged["description"] = _text(fam.get("description", ""), f"{where}: description")
        scene = parse_scene(merged, f"{source} family {fam_name!r}")
        families.append(Family(name=fam_name, scene=scene, description=scene.description))
    return Suite(
        name=name,
        base=base,
        families=tuple(families),
        frames=frames,
        description=_text(data.get("description", ""), f"{source}: description"),
    )


def available_suites() -> list[str]:
    """Names of the suites shipped with the package."""
    return shipped_names("suites")


def load_suite(name_or_path: str | Path) -> Suite:
    """Load a shipped suite by name (``"strips16_ood"``) or any suite TOML file by path."""
    data, source = read_toml(name_or_path, "suites", "suite")
    return parse_suite(data, source)


def suite_frames(suite: Suite, n: int | None, seed: int) -> dict[str, dict[str, np.ndarray]]:
    """Simulated arrays of every family (``n`` frames each, default the suite's), family ``i`` from
    ``SeedSequence(seed, spawn_key=(i,))``: the same seed gives the same frames, bit for bit."""
    from synth.dataset import simulate_shard

    return {
        fam.name: simulate_shard(fam.scene, seed, index, n or suite.frames) for index, fam in enumerate(suite.families)
    }
