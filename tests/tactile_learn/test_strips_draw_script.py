"""scripts/strips_draw.py: issue 12's floors on an independent draw of the ood suite."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_draw


def test_margin_is_over_the_best_classical_method_of_each_family() -> None:
    r = {
        "intersection": {"a": 0.80, "b": 0.50},
        "projection": {"a": 0.70, "b": 0.60},
        "m": {"a": 0.90, "b": 0.55},
    }
    out = strips_draw.compare(r, ["m"])
    assert out["best_classical"] == {"a": 0.80, "b": 0.60}
    assert out["m"]["margin"] == pytest.approx((0.10 - 0.05) / 2)
    assert out["m"]["not_above"] == {"b": pytest.approx(-0.05)}
    assert out["m"]["mean_r"] == pytest.approx(0.725)


def test_a_draw_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "draw.json"
    argv = ["strips16_small", "--seed", "77", "--n", "3", "--json", str(out)]
    assert strips_draw.main(argv) == 0
    result = json.loads(out.read_text())
    assert result["seed"] == 77 and set(result["best_classical"]) == set(result["strips16_small"]["families"])
    assert len(result["best_classical"]) > 5
