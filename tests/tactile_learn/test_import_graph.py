"""The import graph (``scripts/import_graph.py``): the checker finds what it should on a package written
for the test, and the repository's own graph holds no cycle, forbidden arrow or forbidden chain beyond
the ones listed in ``KNOWN_VIOLATIONS`` (a ratchet while the layering is being repaired)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: today's violations, in :func:`_found`'s words. A new one fails the test; one that is fixed must be
#: removed from here (the test fails until it is), so the set only ever shrinks.
KNOWN_VIOLATIONS: set[str] = set()


def _load_checker() -> ModuleType:
    spec = importlib.util.spec_from_file_location("import_graph", ROOT / "scripts" / "import_graph.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("import_graph", module)  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


graph = _load_checker()


def _found(root: Path = ROOT, packages: tuple[str, ...] = graph.PACKAGES, **rules: object) -> set[str]:
    """Every violation of the graph under ``root``, one line each."""
    modules = graph.build(root, packages)
    found = {"cycle: " + " <-> ".join(comp) for comp in graph.cycles(modules)}
    arrows = graph.violations(modules, **{k: v for k, v in rules.items() if k in ("rules", "exempt")})
    found |= {f"arrow: {src} -> {dst}" for src, dst, _ in arrows}
    reach_rules = rules.get("reach_rules", graph.REACH_RULES)
    found |= {
        f"chain: {start} ->* {chain.split(' -> ')[-1]}"
        for start, chain, _ in graph.reach_violations(modules, reach_rules)
    }
    return found


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")


LAYERS = (
    ("low*", "high*", "low sits below high"),
    ("low*", "heavy*", "low runs without heavy"),
)
REACH = (("low.core*", "heavy*", "low.core never reaches heavy"),)


def _synthetic(tmp_path: Path, extra: dict[str, str]) -> set[str]:
    files = {
        "low/__init__.py": "",
        "low/core.py": "import math\n\n\ndef f() -> float:\n    return math.pi\n",
        "low/util.py": "from low.core import f\n",
        "high/__init__.py": "",
        "high/app.py": "from low import util\nimport heavy\n",
        **extra,
    }
    _write(tmp_path, files)
    return _found(tmp_path, ("low", "high"), rules=LAYERS, exempt={}, reach_rules=REACH)


def test_a_clean_package_passes(tmp_path: Path) -> None:
    assert _synthetic(tmp_path, {}) == set()


def test_a_cycle_is_found_even_through_a_lazy_import(tmp_path: Path) -> None:
    lazy_back = "def g() -> None:\n    from low import util  # noqa\n"
    found = _synthetic(tmp_path, {"low/core.py": lazy_back})
    assert found == {"cycle: low.core <-> low.util"}


def test_an_upward_arrow_is_found(tmp_path: Path) -> None:
    found = _synthetic(tmp_path, {"low/util.py": "from low.core import f\nfrom high.app import heavy\n"})
    assert "arrow: low.util -> high.app" in found


def test_a_relative_import_is_resolved(tmp_path: Path) -> None:
    found = _synthetic(tmp_path, {"low/util.py": "from .core import f\nfrom ..high import app\n"})
    # high.app imports low.util: the upward arrow closes a cycle, and both are reported
    assert found == {"arrow: low.util -> high.app", "cycle: high.app <-> low.util"}


def test_a_chain_through_a_lazy_import_is_found_and_type_checking_imports_are_not(tmp_path: Path) -> None:
    typed_only = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import heavy\n"
    assert _synthetic(tmp_path, {"low/core.py": typed_only}) == set()
    lazy = "def f() -> None:\n    from low import util\n"
    util = "def g() -> None:\n    import heavy  # noqa\n"
    found = _synthetic(tmp_path, {"low/core.py": lazy, "low/util.py": util})
    assert "chain: low.core ->* heavy" in found
    assert "arrow: low.util -> heavy" in found


def test_the_repository_graph_holds_no_violation_beyond_the_known_ones() -> None:
    found = _found()
    new = sorted(found - KNOWN_VIOLATIONS)
    fixed = sorted(KNOWN_VIOLATIONS - found)
    assert not new, "new import-graph violations (python scripts/import_graph.py explains them):\n" + "\n".join(new)
    assert not fixed, "fixed, remove them from KNOWN_VIOLATIONS:\n" + "\n".join(fixed)


@pytest.mark.parametrize(
    ("importer", "imported"),
    [
        ("tactile_learn.runtime", "torch"),
        ("tactile_learn.estimators.classical.intersection", "torch"),
        ("synth.scene", "tactile_learn"),
        ("tactile_learn.train", "tactile_learn.cli"),
    ],
)
def test_the_layer_rules_forbid_what_the_architecture_forbids(importer: str, imported: str) -> None:
    # the rules themselves, on a one-arrow graph: a rule deleted from RULES fails here
    modules = {importer: graph.Module(importer, ROOT, 1, imports={imported: True})}
    assert graph.violations(modules), f"{importer} -> {imported} should be forbidden"


def test_training_and_export_may_import_torch_and_the_cli_its_own_modules() -> None:
    allowed = [
        ("tactile_learn.train", "torch"),
        ("tactile_learn.export", "torch"),
        ("tactile_learn.cli.eval", "tactile_learn.cli.common"),
    ]
    for importer, imported in allowed:
        modules = {importer: graph.Module(importer, ROOT, 1, imports={imported: False})}
        assert graph.violations(modules) == [], f"{importer} -> {imported} should be allowed"
