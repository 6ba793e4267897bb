"""Shared fixtures: tiny scenes and datasets so the suite stays fast."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from synth.scene import Scene, load_scene, parse_scene

# `make stress` sets TACTILE_STRESS=1: many more examples per property test
settings.register_profile("fast", max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
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
