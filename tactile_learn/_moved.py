"""Old import paths of modules that moved, kept working without a file at the old place.

A moved module keeps its history as a pure ``git mv`` (a stub left at the old path would make git
treat the move as an edit, and edits made elsewhere to the old file would then not follow it).
``import tactile_learn.thermal_calibration`` still works: this finder answers for the old name with
the module at its new place (the same module object, so both names see the same state).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
from types import ModuleType

__all__ = ["MOVED", "install"]

#: old dotted name -> new dotted name
MOVED: dict[str, str] = {
    "tactile_learn.thermal_calibration": "tactile_learn.calibration.thermal_calibration",
}


class _Alias(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def find_spec(
        self, fullname: str, path: object = None, target: object = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        return importlib.import_module(MOVED[spec.name])

    def exec_module(self, module: ModuleType) -> None:
        """The module at its new place has run already."""


def install() -> None:
    """Put the finder on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _Alias) for f in sys.meta_path):
        sys.meta_path.append(_Alias())
