"""Frozen-dataclass configuration with validation, parsed from plain dicts (TOML).

Every configurable value is a dataclass field declared with :func:`param`, which records its
range, unit and meaning. :func:`from_dict` builds a dataclass from a dict and refuses unknown keys,
wrong types and out-of-range values with a :class:`~synth.errors.ConfigError` that names the key
path (``strips.stimulus.force_n``), so a typo in a scene file never silently falls back to a default.

Supported field types: ``bool``, ``int``, ``float``, ``str``, ``Literal[...]``, nested dataclasses,
``X | None`` of those, ``tuple[X, ...]`` and fixed ``tuple[X, Y]``.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import types
import typing
from collections.abc import Mapping
from typing import Any, Literal, TypeVar, Union, get_args, get_origin

from synth.errors import ConfigError

T = TypeVar("T")

__all__ = ["from_dict", "param", "replace", "to_dict"]


def param(
    default: Any,
    *,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
    unit: str = "",
    doc: str = "",
    ordered: bool = False,
    omit_default: bool = False,
) -> Any:
    """Declare a validated dataclass field.

    ``lo``/``hi`` bound every number in the value (each element of a tuple); ``lo_open`` makes the
    lower bound strict. ``ordered`` requires a tuple to be non-decreasing (a ``[min, max]`` range).
    ``omit_default``: :func:`to_dict` leaves the field out while it holds its default (a field added
    later, so that the digests of scenes written before it existed do not change).
    Tuples and other immutable defaults are stored as plain defaults (dataclasses are frozen).
    """
    meta = {
        "omit_default": omit_default,
        "lo": lo,
        "hi": hi,
        "lo_open": lo_open,
        "hi_open": hi_open,
        "unit": unit,
        "doc": doc,
        "ordered": ordered,
    }
    if dataclasses.is_dataclass(default) and not isinstance(default, type):
        value = default
        return dataclasses.field(default_factory=lambda: dataclasses.replace(value), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", None) or str(tp).replace("typing.", "")


def _check_number(value: Any, tp: type, path: str) -> float | int:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{path}: expected {tp.__name__}, got {type(value).__name__} {value!r}")
    if tp is int and not isinstance(value, int):
        raise ConfigError(f"{path}: expected an integer, got {value!r}")
    if isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"{path}: must be finite, got {value!r}")
    if tp is float:
        # + 0.0 turns -0.0 into 0.0: a range [0.0, -0.0] passes the min <= max check, yet numpy's
        # uniform(0.0, -0.0) refuses it (high - low is -0.0)
        return float(value) + 0.0
    return tp(value)


def _check_range(value: float | int, meta: Mapping[str, Any], path: str) -> None:
    lo, hi = meta.get("lo"), meta.get("hi")
    unit = f" {meta['unit']}" if meta.get("unit") else ""
    if lo is not None and (value < lo or (meta.get("lo_open") and value == lo)):
        rel = ">" if meta.get("lo_open") else ">="
        raise ConfigError(f"{path}: {value!r}{unit} is out of range (must be {rel} {lo}{unit})")
    if hi is not None and (value > hi or (meta.get("hi_open") and value == hi)):
        rel = "<" if meta.get("hi_open") else "<="
        raise ConfigError(f"{path}: {value!r}{unit} is out of range (must be {rel} {hi}{unit})")


def _convert(value: Any, tp: Any, meta: Mapping[str, Any], path: str) -> Any:
    origin = get_origin(tp)
    args = get_args(tp)
    if origin in (Union, types.UnionType):
        options = [a for a in args if a is not type(None)]
        if value is None and len(options) < len(args):
            return None
        errors = []
        for option in options:
            try:
                return _convert(value, option, meta, path)
            except ConfigError as exc:
                errors.append(str(exc))
        raise ConfigError(errors[0] if len(errors) == 1 else f"{path}: {value!r} matches none of {tp}")
    if origin is Literal:
        if value not in args:
            allowed = ", ".join(repr(a) for a in args)
            raise ConfigError(f"{path}: {value!r} is not one of {allowed}")
        return value
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{path}: expected a list, got {type(value).__name__} {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            item_types = [args[0]] * len(value)
        else:
            if len(value) != len(args):
                raise ConfigError(f"{path}: expected {len(args)} values, got {len(value)}")
            item_types = list(args)
        items = tuple(
            _convert(v, t, meta, f"{path}[{i}]") for i, (v, t) in enumerate(zip(value, item_types, strict=True))
        )
        if meta.get("ordered") and any(b < a for a, b in itertools.pairwise(items)):
            raise ConfigError(f"{path}: values must be non-decreasing ([min, max]), got {list(items)}")
        return items
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        if isinstance(value, tp):
            return value
        if not isinstance(value, Mapping):
            raise ConfigError(f"{path}: expected a table, got {type(value).__name__} {value!r}")
        return from_dict(tp, value, path)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{path}: expected true or false, got {value!r}")
        return value
    if tp in (int, float):
        number = _check_number(value, tp, path)
        _check_range(number, meta, path)
        return number
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{path}: expected a string, got {type(value).__name__} {value!r}")
        return value
    raise TypeError(f"{path}: unsupported config type {_type_name(tp)}")  # a bug in a config class


def from_dict(cls: type[T], data: Mapping[str, Any], path: str = "") -> T:
    """Build the frozen dataclass ``cls`` from ``data``, validating every key.

    Raises :class:`ConfigError` naming the offending key for unknown keys, wrong types and values
    out of range. Keys absent from ``data`` take the field's default; a field without default is
    required.
    """
    if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
        raise TypeError(f"{cls!r} is not a dataclass")
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path or cls.__name__}: expected a table, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    prefix = f"{path}." if path else ""
    unknown = sorted(set(data) - set(fields))
    if unknown:
        known = ", ".join(sorted(fields))
        raise ConfigError(f"{prefix}{unknown[0]}: unknown key (known keys here: {known})")
    kwargs: dict[str, Any] = {}
    for name, fld in fields.items():
        key_path = f"{prefix}{name}"
        if name in data:
            kwargs[name] = _convert(data[name], hints[name], fld.metadata, key_path)
        elif fld.default is dataclasses.MISSING and fld.default_factory is dataclasses.MISSING:
            raise ConfigError(f"{key_path}: required key is missing")
    try:
        obj = cls(**kwargs)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}" if path and not str(exc).startswith(path) else str(exc)) from None
    return obj


def _default(fld: dataclasses.Field[Any]) -> Any:
    if fld.default_factory is not dataclasses.MISSING:
        return fld.default_factory()
    return fld.default


def to_dict(obj: Any, full: bool = False) -> Any:
    """Plain JSON/TOML-ready structure of a config object (tuples become lists). Fields declared
    with ``omit_default`` are left out while they hold their default, unless ``full``."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {
            f.name: to_dict(getattr(obj, f.name), full)
            for f in dataclasses.fields(obj)
            if full or not (f.metadata.get("omit_default") and getattr(obj, f.name) == _default(f))
        }
    if isinstance(obj, (list, tuple)):
        return [to_dict(v, full) for v in obj]
    return obj


def replace(obj: T, path: str, value: Any) -> T:
    """Return a copy of the config ``obj`` with the dotted ``path`` set to ``value``, validated."""
    data = to_dict(obj, full=True)
    node = data
    target: Any = obj
    keys = path.split(".")
    for key in keys:
        # walk the dataclasses, not the dict: to_dict leaves out fields that hold their default
        names = {f.name for f in dataclasses.fields(target)} if dataclasses.is_dataclass(target) else set()
        if key not in names:
            raise ConfigError(f"{path}: unknown key")
        if key != keys[-1]:
            node, target = node[key], getattr(target, key)
    node[keys[-1]] = value
    return from_dict(type(obj), data)


def _toml_value(value: Any, path: str) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ConfigError(f"{path}: {value!r} cannot be written to TOML")
        return repr(value)
    if isinstance(value, str):
        return json_string(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v, f"{path}[{i}]") for i, v in enumerate(value)) + "]"
    raise ConfigError(f"{path}: {type(value).__name__} cannot be written to TOML")


def json_string(text: str) -> str:
    """A TOML basic string (TOML's escapes are a subset of JSON's)."""
    import json

    return json.dumps(text, ensure_ascii=False)


def dumps_toml(data: Mapping[str, Any], _prefix: str = "") -> str:
    """Serialise nested dicts of scalars, lists and lists of tables to TOML text (``None``
    values are left out: TOML has no null, and such fields default to ``None``)."""
    scalars, tables, table_arrays = [], [], []
    for key, value in data.items():
        if value is None:
            continue  # TOML has no null: an absent key means "not set" (fields default to None)
        if isinstance(value, Mapping):
            tables.append((key, value))
        elif isinstance(value, (list, tuple)) and value and all(isinstance(v, Mapping) for v in value):
            table_arrays.append((key, value))
        else:
            scalars.append(f"{key} = {_toml_value(value, _prefix + key)}")
    lines = list(scalars)
    for key, value in tables:
        name = f"{_prefix}{key}"
        body = dumps_toml(value, name + ".")
        lines.append("")
        lines.append(f"[{name}]")
        lines.append(body.strip("\n"))
    for key, items in table_arrays:
        name = f"{_prefix}{key}"
        for item in items:
            lines.append("")
            lines.append(f"[[{name}]]")
            lines.append(dumps_toml(item, name + ".").strip("\n"))
    return "\n".join(line for line in lines if line is not None) + "\n"
