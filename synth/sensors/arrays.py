"""Stimuli from named arrays (a user's ``.npz``): the one place that says which array is missing."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from synth.errors import InputError

__all__ = ["optional", "take"]


def optional(arrays: Mapping[str, np.ndarray], name: str, *aliases: str) -> np.ndarray | None:
    """The array ``name`` (or the first of its ``aliases`` present), ``None`` when there is none."""
    for key in (name, *aliases):
        if key in arrays:
            return np.asarray(arrays[key])
    return None


def take(arrays: Mapping[str, np.ndarray], name: str, *aliases: str) -> np.ndarray:
    """The array ``name`` (or the first of its ``aliases`` present); an error naming it, and what
    there is, when it is missing."""
    found = optional(arrays, name, *aliases)
    if found is None:
        known = ", ".join(sorted(arrays)) or "nothing"
        also = f" (or {', '.join(repr(a) for a in aliases)})" if aliases else ""
        raise InputError(f"stimulus: needs an array {name!r}{also}; it has {known}")
    return found
