"""Progress bars for long work (tqdm, an optional extra), silent where there is no terminal."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["progress_bar"]


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
