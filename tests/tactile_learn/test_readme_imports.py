"""Every name the README's Python examples import exists where the README says (a new user copies them
verbatim; the streaming example once imported FrameStream from the wrong module)."""

from __future__ import annotations

import importlib
import re

import pytest

from tests.paths import REPO_ROOT

BLOCK = re.compile(r"```python\n(.*?)```", re.DOTALL)
FROM_IMPORT = re.compile(r"^\s*from\s+([\w.]+)\s+import\s+([\w, ]+?)\s*(?:#.*)?$", re.MULTILINE)


def readme_imports() -> list[tuple[str, str]]:
    text = (REPO_ROOT / "README.md").read_text()
    pairs = []
    for block in BLOCK.findall(text):
        for module, names in FROM_IMPORT.findall(block):
            pairs += [(module, name.strip()) for name in names.split(",") if name.strip()]
    return sorted(set(pairs))


def test_the_readme_has_python_examples() -> None:
    assert len(readme_imports()) >= 5


@pytest.mark.parametrize(("module", "name"), readme_imports())
def test_readme_import_exists(module: str, name: str) -> None:
    if module.split(".")[0] not in ("synth", "tactile_learn"):
        pytest.importorskip(module)
    assert hasattr(importlib.import_module(module), name), f"README: from {module} import {name}"
