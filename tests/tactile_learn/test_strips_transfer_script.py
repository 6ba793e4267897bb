"""scripts/strips_transfer.py: the specialists' margin matrix is read off a strips_unseen result by the family
each card names; a network trained on several datasets or a shipped name stays beside the matrix; a file that
is not such a result, or one with no specialist of the suite, is refused naming the problem."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_transfer

SUITE = "toy_suite"
FAMILIES = ("pin", "ring", "plait")


def write_card(path: Path, scene: str, data_path: str | list[str]) -> str:
    path.with_suffix(".json").write_text(
        json.dumps({"scene": {"name": scene}, "training": {"data": {"path": data_path}}})
    )
    return str(path)


def fake_result(margins: dict[str, list[float]]) -> dict[str, Any]:
    """A strips_unseen result holding only what the matrix reads: each model's margin on each family."""
    families = {
        fam: {"models": {model: {"margin": values[j]} for model, values in margins.items()}}
        for j, fam in enumerate(FAMILIES)
    }
    return {
        "suite": SUITE,
        "seeds": [1],
        "frames_per_family": 4,
        "summary": {model: {} for model in margins},
        "families": families,
    }


@pytest.fixture
def models(tmp_path: Path) -> dict[str, str]:
    return {
        "pin": write_card(tmp_path / "pin.onnx", f"{SUITE}/pin", "data/pin-train"),
        "plait": write_card(tmp_path / "plait.onnx", f"{SUITE}/plait", "data/plait-train"),
        # trained on several datasets: its card names the first one's scene, yet it is no specialist
        "pooled": write_card(tmp_path / "pooled.onnx", f"{SUITE}/pin", ["data/pin-train", "data/ring-train"]),
    }


def test_the_matrix_diagonal_and_off_diagonal_come_from_the_cards_families(models: dict[str, str]) -> None:
    margins = {
        models["pin"]: [0.30, -0.10, 0.05],
        models["plait"]: [-0.20, 0.02, 0.12],
        models["pooled"]: [0.10, 0.01, 0.04],
        "strips16": [0.0, -0.01, 0.02],
    }
    result = fake_result(margins)
    families_of = {m: strips_transfer.card_family(m, SUITE) for m in margins}
    assert families_of == {models["pin"]: "pin", models["plait"]: "plait", models["pooled"]: None, "strips16": None}
    summary = strips_transfer.transfer(result, families_of)
    assert summary["specialists"] == ["pin", "plait"]  # in the suite's family order, the ring has none
    np.testing.assert_allclose(summary["margin"], [margins[models["pin"]], margins[models["plait"]]])
    assert summary["own_family"] == {"pin": 0.30, "plait": 0.12}
    assert np.isclose(summary["own_family_mean"], 0.21)
    assert np.isclose(summary["other_families_mean"], np.mean([-0.10, 0.05, -0.20, 0.02]))
    assert np.isclose(summary["other_families_above_floor"], 0.25)
    assert summary["best_other_specialist"]["ring"] == {"family": "plait", "margin": 0.02}
    assert summary["best_other_specialist"]["pin"] == {"family": "plait", "margin": -0.20}
    assert summary["other_models"] == {models["pooled"]: [0.10, 0.01, 0.04], "strips16": [0.0, -0.01, 0.02]}
    table = strips_transfer.markdown(summary, "cmd")
    assert "| 1 pin | **+0.300** | -0.100 | +0.050 |" in table
    assert "| 3 plait | -0.200 | +0.020 | **+0.120** |" in table


def test_a_family_below_the_rule_is_listed(models: dict[str, str]) -> None:
    result = fake_result({models["pin"]: [-0.01, 0.0, 0.0], models["plait"]: [0.0, 0.0, 0.2]})
    summary = strips_transfer.transfer(result, {models["pin"]: "pin", models["plait"]: "plait"})
    assert summary["own_family_below"] == ["pin"]


def test_main_writes_the_matrix_and_refuses_what_it_cannot_read(tmp_path: Path, models: dict[str, str]) -> None:
    path = tmp_path / "result.json"
    path.write_text(json.dumps(fake_result({models["pin"]: [0.2, 0.0, 0.0], "strips16": [0.0, 0.0, 0.0]})))
    out = tmp_path / "transfer.json"
    assert strips_transfer.main([str(path), "--json", str(out)]) == 0
    written = json.loads(out.read_text())
    assert written["own_family"] == {"pin": 0.2}
    assert out.with_suffix(".md").read_text().startswith("# Specialists across `toy_suite`")
    path.write_text(json.dumps(fake_result({"strips16": [0.0, 0.0, 0.0]})))
    with pytest.raises(SystemExit, match="no model in the result is a specialist"):
        strips_transfer.main([str(path)])
    path.write_text(json.dumps({"suite": SUITE}))
    with pytest.raises(SystemExit, match=r"not a result of scripts/strips_unseen\.py"):
        strips_transfer.main([str(path)])


def test_a_specialist_of_a_family_the_result_lacks_is_refused(models: dict[str, str]) -> None:
    result = fake_result({models["pin"]: [0.2, 0.0, 0.0]})
    with pytest.raises(SystemExit, match="families the result does not hold: teapot"):
        strips_transfer.transfer(result, {models["pin"]: "teapot"})
