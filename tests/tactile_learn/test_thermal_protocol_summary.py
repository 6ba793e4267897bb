"""scripts/thermal_robot_protocol.py's summary over labelled sessions: min, median and how many
labelled sessions hold each of issue 11's floors (tiny made-up results, no recordings)."""

from __future__ import annotations

import sys
from typing import Any

import pytest

from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import thermal_robot_protocol


def session(name: str, heated_4s: float, all_2s: float) -> dict[str, Any]:
    def table(at: dict[str, float]) -> dict[str, Any]:
        return {"all": {"0.5": 0.5, "1.0": 0.6, "2.0": 0.7, "4.0": 0.8, **at}}

    return {
        "labelled": name,
        "heated": {"methods": {"m": table({"4.0": heated_4s})}},
        "all": {"methods": {"m": table({"2.0": all_2s})}},
    }


def test_floor_summary_counts_the_sessions_that_hold_each_floor() -> None:
    # 80 / 81 holds the 0.98 floor, 79 / 81 does not; 0.90 exactly holds the heated one
    results = [session("A", 0.90, 80 / 81), session("B", 0.95, 79 / 81), session("C", 0.89, 1.0)]
    summary = thermal_robot_protocol.floor_summary(results)
    heated, both = summary["heated"]["m"], summary["all"]["m"]
    assert heated["floor_0.9_at_4.0_s"] == {"held": 2, "of": 3, "sessions": ["A", "B"]}
    assert both["floor_0.98_at_2.0_s"] == {"held": 2, "of": 3, "sessions": ["A", "C"]}
    assert "floor_0.98_at_2.0_s" not in heated and "floor_0.9_at_4.0_s" not in both
    assert both["min"]["2.0"] == pytest.approx(79 / 81) and both["median"]["2.0"] == pytest.approx(80 / 81)
    assert heated["min"]["4.0"] == 0.89 and heated["median"]["4.0"] == 0.90
