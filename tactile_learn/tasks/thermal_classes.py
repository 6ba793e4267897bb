"""What a thermal scene classifies: its classes (names, families, effusivities), the labels of
materials and recordings against them, and the keys of its input channels' records."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from synth.errors import DataError
from synth.materials import Material
from synth.scene import Scene
from synth.sensors.thermal import ThermalConfig

__all__ = [
    "NONE",
    "Classes",
    "channel_keys",
    "class_names",
    "classes_of",
    "labels_from_materials",
    "recording_labels",
    "thermal_config",
]

#: the last class of every prediction: the pixel touches nothing
NONE = "none"


def thermal_config(scene: Scene) -> ThermalConfig:
    """The scene's thermal config; a DataError for a scene of another sensor."""
    if not isinstance(scene.sensor, ThermalConfig):
        raise DataError(f"scene {scene.name!r} is not a thermal scene (task {scene.task!r})")
    return scene.sensor


@dataclass(frozen=True)
class Classes:
    """What a scene classifies: names, each class's family index (-1: mixed) and effusivity."""

    names: tuple[str, ...]
    families: np.ndarray
    effusivity: np.ndarray

    def __len__(self) -> int:
        return len(self.names)


def classes_of(source: ThermalConfig | Sequence[Material]) -> Classes:
    """The classes of a scene's config (its user classes, else its materials) or of materials."""
    if isinstance(source, ThermalConfig):
        mats, of = source.material_list, source.class_of_material
        names = source.class_names
    else:
        mats, of = tuple(source), np.arange(len(source))
        names = tuple(m.name for m in mats)
    families, eff = [], []
    for k in range(len(names)):
        members = [m for m, c in zip(mats, of, strict=True) if c == k]
        fam = {m.family_index for m in members}
        families.append(fam.pop() if len(fam) == 1 else -1)
        eff.append(float(np.exp(np.mean([np.log(m.effusivity) for m in members]))))
    return Classes(names, np.array(families), np.array(eff))


def recording_labels(config: ThermalConfig) -> dict[str, Any]:
    """How :func:`~tactile_learn.thermal_recordings.read_recordings` reads labels for a scene:
    against its classes (by name) or its materials."""
    if config.objects.classes:
        names = config.class_names
        of = config.class_of_material
        mats = config.material_list
        return {
            "classes": {n: tuple(m.name for m, c in zip(mats, of, strict=True) if c == k) for k, n in enumerate(names)}
        }
    return {"materials": [m.name for m in config.material_list]}


def class_names(scene: Scene) -> tuple[str, ...]:
    """The prediction's classes: the scene's classes (or materials), then ``none``."""
    return (*thermal_config(scene).class_names, NONE)


def labels_from_materials(
    material_index: np.ndarray, n_materials: int, config: ThermalConfig | None = None
) -> np.ndarray:
    """Class labels (int64): the class of the material index (``config``'s classes; without a
    config the material itself), ``none`` where it is -1."""
    idx = np.asarray(material_index).astype(np.int64)
    if config is None:
        return np.where(idx < 0, n_materials, idx)
    of = config.class_of_material
    return np.where(idx < 0, len(config.class_names), of[np.clip(idx, 0, len(of) - 1)])


def channel_keys(config: ThermalConfig) -> tuple[str, ...]:
    """EvalData keys of the records of the scene's input channels (heated first)."""
    return tuple("record" if c == "heated" else f"record_{c}" for c in config.channels)
