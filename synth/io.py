"""Atomic file writes and checksums.

Every file this project writes goes to a temporary name in the same folder, is flushed to disk and
then renamed over the final name, so a reader never sees a half-written file under a final name,
whatever kills the writer and when.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np

__all__ = [
    "atomic_open",
    "atomic_save_npy",
    "atomic_save_npz",
    "atomic_write_json",
    "atomic_write_text",
    "json_dumps",
    "json_ready",
    "sha256_file",
]


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "wb") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on success it replaces ``path`` atomically."""
    final = Path(path)
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = final.with_name(f".{final.name}.tmp-{os.getpid()}")
    try:
        with open(tmp, mode) as handle:  # noqa: PTH123 - mode is chosen by the caller
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        tmp.replace(final)
    finally:
        if tmp.exists():
            tmp.unlink()


def atomic_write_text(path: str | Path, text: str) -> None:
    with atomic_open(path, "w") as handle:
        handle.write(text)


def json_ready(value: Any) -> Any:
    """``value`` as strict JSON data: NaN/inf (not valid JSON) become ``None``, numpy scalars and
    arrays Python numbers and lists, tuples lists, mapping keys strings, any other object its ``str``."""
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return str(value)  # paths, dtypes, enums: their readable form (what a report wants)


def json_dumps(data: Any) -> str:
    """Indented strict JSON of ``data`` (see :func:`json_ready`)."""
    return json.dumps(json_ready(data), indent=2, allow_nan=False)


def atomic_write_json(path: str | Path, data: Any) -> None:
    """``data`` as strict JSON (:func:`json_ready`), written atomically: the one JSON writer."""
    atomic_write_text(path, json_dumps(data) + "\n")


def atomic_save_npy(path: str | Path, array: np.ndarray) -> None:
    """Save ``array`` as ``.npy`` (memory-mappable) atomically."""
    with atomic_open(path, "wb") as handle:
        np.save(handle, np.ascontiguousarray(array), allow_pickle=False)


def atomic_save_npz(path: str | Path, arrays: dict[str, np.ndarray]) -> None:
    """Save named arrays as an (uncompressed) ``.npz`` atomically."""
    named: dict[str, Any] = dict(arrays)
    with atomic_open(path, "wb") as handle:
        np.savez(handle, **named)


def sha256_file(path: str | Path, chunk: int = 1 << 20) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:  # noqa: PTH123 - streaming read
        while block := handle.read(chunk):
            digest.update(block)
    return digest.hexdigest()
