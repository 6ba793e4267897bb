"""Thermal material library: handbook properties with their spread, grouped in families.

The table lives in ``synth/data/materials.toml`` (18 materials of the reference table, five
families: metal, stone/glass, polymer, wood, foam). A simulated object draws each of its three
properties (conductivity ``k``, density ``rho``, specific heat ``c``) uniformly within
``nominal * (1 +- spread)``; its effusivity ``e = sqrt(k rho c)`` and diffusivity
``alpha = k / (rho c)`` follow. :func:`effusivity_range` gives the interval a material's effusivity
can take, so overlaps (materials no method can tell apart from ``e`` alone) are computable.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources

import numpy as np

from synth.errors import ConfigError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = [
    "FAMILIES",
    "Material",
    "MaterialSample",
    "effusivity_range",
    "family_materials",
    "get_material",
    "library",
    "load_class_map",
    "material_names",
    "resolve_label",
    "resolve_materials",
    "sample_properties",
]

#: material families, in the order family indices use
FAMILIES: tuple[str, ...] = ("metal", "stone/glass", "polymer", "wood", "foam")


@dataclass(frozen=True)
class Material:
    """Nominal properties of one material and the relative half-width of their spread."""

    name: str
    family: str
    k_w_mk: float
    rho_kg_m3: float
    c_j_kgk: float
    #: relative half-widths of (k, rho, c)
    spread: tuple[float, float, float]

    @property
    def effusivity(self) -> float:
        """``sqrt(k rho c)`` in W s^0.5 / (m^2 K)."""
        return float(np.sqrt(self.k_w_mk * self.rho_kg_m3 * self.c_j_kgk))

    @property
    def diffusivity_mm2_s(self) -> float:
        """``k / (rho c)`` in mm^2/s."""
        return 1e6 * self.k_w_mk / (self.rho_kg_m3 * self.c_j_kgk)

    @property
    def family_index(self) -> int:
        return FAMILIES.index(self.family)


@dataclass(frozen=True)
class MaterialSample:
    """Properties drawn for a batch of objects (arrays of one shape)."""

    k_w_mk: np.ndarray
    rho_kg_m3: np.ndarray
    c_j_kgk: np.ndarray

    @property
    def effusivity(self) -> np.ndarray:
        return np.sqrt(self.k_w_mk * self.rho_kg_m3 * self.c_j_kgk)

    @property
    def diffusivity_m2_s(self) -> np.ndarray:
        return self.k_w_mk / (self.rho_kg_m3 * self.c_j_kgk)


@functools.cache
def library() -> tuple[Material, ...]:
    """Every material of the shipped table, in table order."""
    text = (resources.files("synth") / "data" / "materials.toml").read_text(encoding="utf-8")
    rows = tomllib.loads(text)["material"]
    out = []
    for row in rows:
        spread = tuple(float(s) for s in row["spread"])
        if row["family"] not in FAMILIES or len(spread) != 3 or not all(0 <= s < 1 for s in spread):
            raise ConfigError(f"materials.toml: bad row for {row.get('name')!r}")  # a broken shipped table
        out.append(
            Material(
                name=str(row["name"]),
                family=str(row["family"]),
                k_w_mk=float(row["k_w_mk"]),
                rho_kg_m3=float(row["rho_kg_m3"]),
                c_j_kgk=float(row["c_j_kgk"]),
                spread=(spread[0], spread[1], spread[2]),
            )
        )
    return tuple(out)


def material_names() -> tuple[str, ...]:
    return tuple(m.name for m in library())


def get_material(name: str) -> Material:
    """The material called ``name`` (case-insensitive; ``-`` and spaces read as ``_``)."""
    key = name.strip().lower().replace("-", "_").replace(" ", "_")
    for material in library():
        if material.name == key:
            return material
    raise ConfigError(f"unknown material {name!r} (library: {', '.join(material_names())})")


def family_materials(family: str) -> tuple[Material, ...]:
    """Every library material of ``family`` (one of :data:`FAMILIES`, case-insensitive)."""
    key = family.strip().lower()
    if key not in FAMILIES:
        raise ConfigError(f"unknown material family {family!r} (families: {', '.join(FAMILIES)})")
    return tuple(m for m in library() if m.family == key)


def accepted_labels(class_map: dict[str, tuple[str, ...]] | None = None) -> str:
    """What a label may be, for error messages."""
    mapped = f"; your classes: {', '.join(class_map)}" if class_map else ""
    return f"materials: {', '.join(material_names())}; families: {', '.join(FAMILIES)}{mapped}"


def resolve_label(label: str, class_map: dict[str, tuple[str, ...]] | None = None) -> tuple[Material, ...]:
    """The library materials a touch label stands for: a class of ``class_map`` (its entries are
    materials or families), a library material, or a family (all its materials). An unknown label
    is a :class:`ConfigError` that lists what is accepted."""
    key = label.strip()
    if class_map and key in class_map:
        out: list[Material] = []
        for entry in class_map[key]:
            for m in resolve_label(entry):
                if m not in out:
                    out.append(m)
        return tuple(out)
    try:
        return (get_material(key),)
    except ConfigError:
        pass
    if key.lower() in FAMILIES:
        return family_materials(key)
    raise ConfigError(f"unknown label {label!r} (accepted: {accepted_labels(class_map)})")


def load_class_map(path: str) -> dict[str, tuple[str, ...]]:
    """User classes from a TOML file: a ``[classes]`` table of ``name = ["material or family", ...]``;
    every entry must resolve (a :class:`ConfigError` names the file and the entry otherwise)."""
    from pathlib import Path

    source = Path(path)
    try:
        data = tomllib.loads(source.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{source}: cannot be read ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML: {exc}") from None
    table = data.get("classes")
    if not isinstance(table, dict) or not table:
        raise ConfigError(f'{source}: expected a [classes] table, e.g. metal = ["aluminium"], wood = ["wood"]')
    out: dict[str, tuple[str, ...]] = {}
    for name, entries in table.items():
        if isinstance(entries, str):
            entries = [entries]
        if not isinstance(entries, list) or not entries or not all(isinstance(e, str) for e in entries):
            raise ConfigError(f"{source}: classes.{name}: expected a list of material or family names")
        for entry in entries:
            try:
                resolve_label(entry)
            except ConfigError as exc:
                raise ConfigError(f"{source}: classes.{name}: {exc}") from None
        out[str(name)] = tuple(entries)
    return out


def resolve_materials(names: Sequence[str]) -> tuple[Material, ...]:
    """The materials named in a scene; an empty list means the whole library."""
    if not names:
        return library()
    materials = tuple(get_material(n) for n in names)
    seen = [m.name for m in materials]
    if len(set(seen)) != len(seen):
        raise ConfigError(f"materials: listed twice: {sorted({n for n in seen if seen.count(n) > 1})}")
    return materials


def effusivity_range(material: Material) -> tuple[float, float]:
    """Smallest and largest effusivity a sample of ``material`` can have."""
    sk, sr, sc = material.spread
    lo = material.k_w_mk * (1 - sk) * material.rho_kg_m3 * (1 - sr) * material.c_j_kgk * (1 - sc)
    hi = material.k_w_mk * (1 + sk) * material.rho_kg_m3 * (1 + sr) * material.c_j_kgk * (1 + sc)
    return float(np.sqrt(lo)), float(np.sqrt(hi))


def sample_properties(
    materials: Sequence[Material], index: np.ndarray, rng: np.random.Generator, spread_scale: float = 1.0
) -> MaterialSample:
    """Draw properties for objects of materials ``materials[index]`` (any shape of ``index``).

    Each property is uniform in ``nominal * (1 +- spread_scale * spread)``.
    """
    nominal = np.array([[m.k_w_mk, m.rho_kg_m3, m.c_j_kgk] for m in materials], dtype=np.float64)
    spread = np.array([m.spread for m in materials], dtype=np.float64) * spread_scale
    idx = np.asarray(index)
    u = rng.uniform(-1.0, 1.0, size=(*idx.shape, 3))
    props = nominal[idx] * (1.0 + spread[idx] * u)
    return MaterialSample(k_w_mk=props[..., 0], rho_kg_m3=props[..., 1], c_j_kgk=props[..., 2])
