"""Folders written by ``tactile-learn learn-object``, read without torch.

A learned object's folder holds its specialist (``specialist.onnx`` with its card) and ``object.json``,
written last: a folder without a readable ``object.json`` of the right kind is no learned object (an
interrupted run, or something else). Wherever a strip method is named (``eval --method``, ``bench``,
``tactile-learn objects --object NAME=DIR``), such a folder stands for its specialist, and
``tactile-learn objects --learned DIR`` takes every learned object in ``DIR``, its router fitted on each
object's own readings (the ones it was learned from, which ``object.json`` names with their checksum: frames
of the real object, where rendered ones are an approximation; docs/strips.md measures both).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from synth.errors import ConfigError, DataError, ModelError

__all__ = [
    "OBJECT_FILE",
    "OBJECT_KIND",
    "RENDERED_TRAIN",
    "RENDERED_VAL",
    "is_learned_object",
    "learned_objects_in",
    "learned_readings",
    "learned_specialist",
    "readings_digest",
    "readings_record",
]

OBJECT_FILE = "object.json"
OBJECT_KIND = "tactile-learn learned object"
#: the folder's rendered training frames: the object's frames a known-objects router is fitted on
#: (named here, not taken from the card, whose path is relative to wherever the command ran)
RENDERED_TRAIN = "train"
#: its rendered validation frames (the specialist's card calibrates its flag threshold on them)
RENDERED_VAL = "val"


def readings_digest(readings: np.ndarray) -> str:
    """SHA-256 of the readings as float32, with their shape: the same frames give the same digest whatever
    file they are stored in."""
    arr = np.ascontiguousarray(readings, dtype=np.float32)
    return hashlib.sha256(repr(arr.shape).encode() + arr.tobytes()).hexdigest()


def readings_record(path: str, readings: np.ndarray) -> dict[str, Any]:
    """What ``object.json`` records of the readings an object was learned from."""
    return {"path": path, "frames": len(readings), "sha256": readings_digest(readings)}


def _record(folder: Path) -> dict[str, Any]:
    record_file = folder / OBJECT_FILE
    try:
        record = json.loads(record_file.read_text())
    except FileNotFoundError:
        raise ModelError(f"{folder}: no {OBJECT_FILE}; not a learned object (or its run did not finish)") from None
    except (OSError, ValueError) as exc:
        raise ModelError(f"{record_file}: not readable JSON ({exc})") from None
    if not isinstance(record, dict) or record.get("kind") != OBJECT_KIND:
        raise ModelError(f"{record_file}: not a learned object's record (kind must be {OBJECT_KIND!r})")
    return record


def is_learned_object(spec: str | Path) -> bool:
    """``spec`` is a folder with an ``object.json`` (whether that file is sound is :func:`learned_specialist`'s
    question: it says what is wrong)."""
    path = Path(spec)
    return path.is_dir() and (path / OBJECT_FILE).is_file()


def learned_specialist(folder: str | Path) -> Path:
    """The specialist ``.onnx`` of a learned object's folder, checked to exist with its card."""
    folder = Path(folder)
    record = _record(folder)
    name = record.get("specialist")
    if not isinstance(name, str) or not name or Path(name).name != name:
        raise ModelError(f"{folder / OBJECT_FILE}: 'specialist' must name a model file in the folder, got {name!r}")
    model = folder / name
    if not model.is_file() or not model.with_suffix(".json").is_file():
        raise ModelError(f"{folder}: its specialist {name} or the card beside it is missing")
    return model


def learned_readings(folder: str | Path) -> Path:
    """The readings a learned object was learned from, found where ``object.json`` names them and checked
    against its checksum (moved, edited or other frames are refused by name: give them with ``--data``)."""
    folder = Path(folder)
    record = _record(folder)
    source = record.get("readings")
    if not isinstance(source, dict) or not isinstance(source.get("path"), str):
        raise DataError(
            f"{folder / OBJECT_FILE} names no readings (learned by an older version): give its frames with --data"
        )
    from synth.dataset import load_arrays  # only here: resolving a method needs no dataset code

    path = Path(source["path"])
    try:
        readings = load_arrays(path, ["readings"])["readings"]
    except (DataError, OSError) as exc:
        raise DataError(
            f"{folder}: the readings it was learned from, {path}, cannot be read ({exc}); give its frames with --data"
        ) from None
    if readings_digest(readings) != source.get("sha256"):
        raise DataError(
            f"{folder}: {path} no longer holds the readings it was learned from (checksum differs); "
            "give its frames with --data"
        )
    return path


def learned_objects_in(folder: str | Path) -> dict[str, Path]:
    """Every learned object directly in ``folder``, by subfolder name (sorted): name -> specialist."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError(f"--learned: {folder} is not a folder")
    found = {sub.name: learned_specialist(sub) for sub in sorted(folder.iterdir()) if is_learned_object(sub)}
    if not found:
        raise ConfigError(f"--learned: {folder} holds no learned object (a subfolder with {OBJECT_FILE})")
    return found
