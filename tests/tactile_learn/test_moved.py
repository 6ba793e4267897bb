"""Old import paths of moved modules resolve to the module at its new place."""

from __future__ import annotations

import importlib

import pytest

from tactile_learn._moved import MOVED


@pytest.mark.parametrize(("old", "new"), sorted(MOVED.items()))
def test_an_old_name_is_the_new_module(old: str, new: str) -> None:
    assert importlib.import_module(old) is importlib.import_module(new)


def test_other_names_are_not_answered() -> None:
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("tactile_learn.no_such_module")
