"""Helpers shared by the subcommands: argument types, progress bars, JSON output."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from synth.io import atomic_write_json

__all__ = ["json_ready", "on_off", "positive_int", "progress_bar", "write_json"]


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}")
    return value


def on_off(text: str) -> bool:
    if text.lower() in ("on", "true", "yes", "1"):
        return True
    if text.lower() in ("off", "false", "no", "0"):
        return False
    raise argparse.ArgumentTypeError(f"expected on or off, got {text!r}")


class _Bar:
    """The slice of tqdm's interface the commands use; a no-op when there is no terminal."""

    def __init__(self, total: int | None, desc: str, unit: str, enabled: bool) -> None:
        self._bar: Any = None
        if enabled:
            try:
                from tqdm import tqdm
            except ImportError:  # tqdm is an optional extra: no bar without it
                return
            self._bar = tqdm(total=total, desc=desc, unit=unit, dynamic_ncols=True, file=sys.stderr)

    def update(self, n: int = 1) -> None:
        if self._bar is not None:
            self._bar.update(n)

    def set_postfix_str(self, text: str) -> None:
        if self._bar is not None:
            self._bar.set_postfix_str(text)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


@contextmanager
def progress_bar(total: int | None, desc: str, unit: str = "it", enabled: bool | None = None) -> Iterator[_Bar]:
    """A tqdm bar on an interactive terminal (or when ``enabled``), else a silent stand-in."""
    bar = _Bar(total, desc, unit, sys.stderr.isatty() if enabled is None else enabled)
    try:
        yield bar
    finally:
        bar.close()


def json_ready(value: Any) -> Any:
    """Replace NaN/inf (not valid JSON) by None and numpy scalars by Python numbers."""
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if hasattr(value, "item") and callable(value.item) and getattr(value, "ndim", 1) == 0:
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_json(path: str | Path, data: Any) -> None:
    atomic_write_json(path, json_ready(data))


def dumps(data: Any) -> str:
    return json.dumps(json_ready(data), indent=2)
