"""scripts/strips_known_objects.py: the routed path answers each frame with the specialist the classifier picks;
its figures recompute from the suite's frames; models that are no one-object specialists of the suite are
refused naming the problem."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from synth.suite import load_suite
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.suites import suite_eval_data
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_family_data
import strips_known_objects

SUITE = "strips16_unseen4"
FAMILIES = ("card_corner", "bead_loop")
MODEL = "strips16_small"


def stand_in_specialist(folder: Path, family: str, data: Path) -> str:
    """The small shipped model with a card saying it was trained on ``family``'s frames in ``data``."""
    folder.mkdir()
    shutil.copyfile(REPO_ROOT / "models" / f"{MODEL}.onnx", folder / "specialist.onnx")
    card = json.loads((REPO_ROOT / "models" / f"{MODEL}.json").read_text())
    card["scene"]["name"] = f"{SUITE}/{family}"
    card["training"]["data"] = {"path": str(data)}
    (folder / "specialist.json").write_text(json.dumps(card))
    return str(folder / "specialist.onnx")


def test_routed_r_takes_each_frame_from_the_chosen_model() -> None:
    per_model = np.array([[0.1, 0.2, 0.3], [0.9, 0.8, 0.7]])
    np.testing.assert_array_equal(strips_known_objects.routed_r(per_model, np.array([1, 0, 1])), [0.9, 0.2, 0.7])


def test_models_that_are_no_specialists_are_refused(tmp_path: Path) -> None:
    one = stand_in_specialist(tmp_path / "one", FAMILIES[0], tmp_path / "d1")
    two = stand_in_specialist(tmp_path / "two", FAMILIES[0], tmp_path / "d2")
    with pytest.raises(SystemExit, match="names no single family of strips16_unseen4"):
        strips_known_objects.specialists_of([one, "strips16"], SUITE)
    with pytest.raises(SystemExit, match="two specialists of card_corner"):
        strips_known_objects.specialists_of([one, two], SUITE)
    with pytest.raises(SystemExit, match="at least two objects"):
        strips_known_objects.specialists_of([one], SUITE)


def test_the_routed_figures_recompute_from_the_frames(tmp_path: Path) -> None:
    models = []
    for i, family in enumerate(FAMILIES):
        data = tmp_path / f"data-{family}"
        strips_family_data.write_family(SUITE, family, 40, 70 + i, data)
        models.append(stand_in_specialist(tmp_path / family, family, data))
    out = tmp_path / "known.json"
    argv = [*models, "--suite", SUITE, "--train-frames", "40", "--n", "12", "--seeds", "3", "--json", str(out)]
    assert strips_known_objects.main(argv) == 0
    result = json.loads(out.read_text())
    suite = load_suite(SUITE)
    frames = suite_eval_data(suite, 12, 3)
    # every specialist is the same network, so any routing gives its r: the routed and oracle margins agree
    for family in FAMILIES:
        data = frames[family]
        r = {
            m: float(
                np.nanmean(
                    pearson_per_frame(
                        resolve_method("strips", m, suite.base).predict(data.inputs), data.truth["pressure"]
                    )
                )
            )
            for m in ("intersection", "projection", MODEL, "strips16")
        }
        best = max(r["intersection"], r["projection"])
        fam = result["families"][family]
        assert np.isclose(fam["best_rule"], best)
        assert np.isclose(fam["oracle"], r[MODEL] - best)
        assert np.isclose(fam["routed"], r[MODEL] - best)
        assert np.isclose(fam["default"], r["strips16"] - best)
        assert 0.0 <= fam["right_share"] <= 1.0
    assert np.isclose(result["mean"]["oracle"], np.mean([result["families"][f]["oracle"] for f in FAMILIES]))
    assert out.with_suffix(".md").read_text().startswith("# A router over one-object specialists")
