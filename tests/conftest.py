"""Shared fixtures: tiny scenes and datasets so the suite stays fast."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from synth.scene import Scene, load_scene, parse_scene

# `make stress` sets TACTILE_STRESS=1: many more examples per property test, freshly random each run
# (it explores). `make test` draws the same examples every run (derandomize): CI is reproducible,
# and a case that stress finds is fixed and pinned by a plain test, not left to chance.
settings.register_profile(
    "fast", max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile("stress", max_examples=600, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("stress" if os.environ.get("TACTILE_STRESS") else "fast")


def tiny_strips_scene(**stimuli: object) -> Scene:
    """A 6 x 5 strip array: small enough for brute-force checks, not square (catches transposes)."""
    data = load_scene("strips16").to_dict()
    data["name"] = "tiny"
    data["strips"]["geometry"].update(n_rows=6, n_cols=5)
    data["strips"]["stimuli"].update(stimuli)
    return parse_scene(data, "tiny")


@pytest.fixture()
def tiny_scene() -> Scene:
    return tiny_strips_scene()


@pytest.fixture()
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


@pytest.fixture()
def workdir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    return tmp_path


# ---- `make stress` summary: hypothesis cases tried and failed, per test module ------------------

_CASES: dict[str, dict[str, int]] = {}
_CURRENT: dict[str, str] = {}


def _category(nodeid: str) -> str:
    module = Path(nodeid.split("::")[0]).stem
    return module.removeprefix("test_")


def _count_case(observation: object) -> None:
    if getattr(observation, "type", None) != "test_case":
        return
    category = _CURRENT.get("category", "other")
    counts = _CASES.setdefault(category, {"tried": 0, "failed": 0})
    counts["tried"] += 1
    if getattr(observation, "status", "") == "failed":
        counts["failed"] += 1


if os.environ.get("TACTILE_STRESS"):
    from hypothesis.internal.observability import add_observability_callback

    add_observability_callback(_count_case)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item: pytest.Item) -> object:
    _CURRENT["category"] = _category(item.nodeid)
    yield


def pytest_terminal_summary(terminalreporter: object, exitstatus: int) -> None:
    if not _CASES:
        return
    write = terminalreporter.write_line  # type: ignore[attr-defined]
    write("")
    write("stress summary (hypothesis cases per category)")
    for category, counts in sorted(_CASES.items()):
        write(f"  {category:28s} {counts['tried']:7d} cases tried, {counts['failed']} failures")
    total = sum(c["tried"] for c in _CASES.values())
    failed = sum(c["failed"] for c in _CASES.values())
    write(f"  {'total':28s} {total:7d} cases tried, {failed} failures")
