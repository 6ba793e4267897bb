"""The one JSON writer: strict JSON whatever numpy hands it, written atomically."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from synth.io import atomic_write_json, json_dumps, json_ready


def test_json_ready_makes_strict_json() -> None:
    data = {
        1: np.float32(0.5),
        "nan": float("nan"),
        "inf": np.float64(np.inf),
        "arr": np.arange(3, dtype=np.int16),
        "tuple": (np.int64(2), None, True),
        "path": Path("a") / "b",
    }
    ready = json_ready(data)
    assert ready == {"1": 0.5, "nan": None, "inf": None, "arr": [0, 1, 2], "tuple": [2, None, True], "path": "a/b"}
    json.loads(json_dumps(data))  # allow_nan=False inside: a NaN left over would raise


def test_atomic_write_json_replaces_whole_file(tmp_path: Path) -> None:
    target = tmp_path / "out.json"
    atomic_write_json(target, {"a": [1.0, float("nan")]})
    assert json.loads(target.read_text()) == {"a": [1.0, None]}
    with pytest.raises(TypeError):  # a failure while writing leaves the old file and no temporary
        atomic_write_json(target, {"bad": object.__new__(_Unwritable)})
    assert json.loads(target.read_text()) == {"a": [1.0, None]}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


class _Unwritable:
    def __str__(self) -> str:
        raise TypeError("cannot be written")
