"""scripts/strips_learned_objects.py on a few frames: each learned object is judged on its own family only, its
margin and the reference's are r minus the best rule's r on the same frames, recomputed here, and a folder
with no learned object of the suite is refused."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from synth.dataset import generate, load_arrays
from synth.scene import load_scene, read_toml
from synth.suite import Suite, parse_suite
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.strips_guard import CheckedStripModel
from tactile_learn.suites import suite_eval_data
from tests.paths import REPO_ROOT
from tests.tactile_learn.test_known_objects import bundle_folder

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_learned_objects

MODELS = REPO_ROOT / "models"


def two_families() -> Suite:
    data, _ = read_toml("strips16_unseen", "suites", "suite")
    picked = [f for f in data["families"] if f["name"] in ("bottle_cap", "five_fingertips")]
    return parse_suite({**data, "families": picked}, "two families")


def stand_in(folder: Path, model: str) -> Path:
    """A learned object's folder holding a shipped model as its specialist."""
    folder.mkdir(parents=True)
    for suffix in (".onnx", ".json"):
        shutil.copy(MODELS / f"{model}{suffix}", folder / f"specialist{suffix}")
    (folder / "object.json").write_text(json.dumps({"fit": {"residual_median": 0.2}, "command": "tactile-learn x"}))
    return folder / "specialist.onnx"


def test_margins_follow_their_definition(tmp_path: Path) -> None:
    suite = two_families()
    learned = tmp_path / "learned"
    model = stand_in(learned / "bottle_cap", "strips16_small")  # five_fingertips has none: not judged
    reference = tmp_path / "ref" / "bottle_cap.onnx"
    reference.parent.mkdir()
    for suffix in (".onnx", ".json"):
        shutil.copy(MODELS / f"strips16_spheres{suffix}", reference.with_suffix(suffix))
    result = strips_learned_objects.judge(
        suite, learned, ["strips16"], str(tmp_path / "ref" / "{family}.onnx"), [3, 4], 12, log=lambda _: None
    )
    assert list(result["families"]) == ["bottle_cap"]
    fam = result["families"]["bottle_cap"]
    per_seed: dict[str, list[float]] = {"learned": [], "reference": [], "strips16": []}
    for seed in (3, 4):
        data = suite_eval_data(suite, 12, seed)["bottle_cap"]
        truth = data.truth["pressure"]
        r = {
            name: float(
                np.nanmean(pearson_per_frame(resolve_method("strips", spec, suite.base).predict(data.inputs), truth))
            )
            for name, spec in (
                ("intersection", "intersection"),
                ("projection", "projection"),
                ("strips16", "strips16"),
                ("learned", str(model)),
                ("reference", str(reference)),
            )
        }
        for name in per_seed:
            per_seed[name].append(r[name] - r[fam["best_rule"]])
    for name, values in per_seed.items():
        assert np.allclose(fam["margin_per_seed"][name], values)
        assert np.isclose(fam["margin"][name], np.mean(values))
    s = result["summary"]
    assert (
        np.isclose(s["share_of_reference"], fam["margin"]["learned"] / fam["margin"]["reference"])
        or fam["margin"]["reference"] <= 0
    )
    assert fam["fit_residual_median"] == 0.2
    table = strips_learned_objects.markdown(result)
    assert "| bottle_cap |" in table and "five_fingertips" not in table


def test_without_learned_objects_every_family_is_judged_with_the_models() -> None:
    result = strips_learned_objects.judge(two_families(), None, ["strips16_small"], None, [3], 8, log=lambda _: None)
    assert set(result["families"]) == {"bottle_cap", "five_fingertips"}
    assert all(set(f["margin"]) == {"strips16_small"} for f in result["families"].values())
    assert "share_of_reference" not in result["summary"]


def test_a_folder_without_learned_objects_is_refused(tmp_path: Path) -> None:
    with pytest.raises(SystemExit, match=r"no FAMILY/specialist\.onnx"):
        strips_learned_objects.judge(two_families(), tmp_path, [], None, [3], 4, log=lambda _: None)


def test_the_own_readings_check_compares_its_residuals_on_own_and_rendered_frames(tmp_path: Path) -> None:
    suite = two_families()
    learned = tmp_path / "learned"
    model = stand_in(learned / "bottle_cap", "strips16_small")
    generate(load_scene("strips16"), 40, 21, model.parent / "val")  # stands in for its rendered frames
    own = suite_eval_data(suite, 30, 22)["bottle_cap"].inputs
    np.savez(tmp_path / "bottle_cap-own.npz", readings=own)
    result = strips_learned_objects.judge(
        suite,
        learned,
        [],
        None,
        [3],
        8,
        log=lambda _: None,
        guard_readings=str(tmp_path / "{family}-own.npz"),
        guard_frames=25,
    )
    check = result["families"]["bottle_cap"]["own_readings_check"]
    checked = CheckedStripModel(model, scene=suite.base).prepare()
    on_own = checked.check(own[:25])  # every frame of the family has a press: none is left out
    on_rendered = checked.check(load_arrays(model.parent / "val", ["readings"])["readings"])
    assert check["frames"] == 25
    assert np.isclose(check["residual_own"], np.median(on_own["residual"]))
    assert np.isclose(check["residual_ratio"], check["residual_own"] / np.median(on_rendered["residual"]))
    assert np.isclose(check["flagged_own"], np.mean(on_own["flagged"]))
    assert "flagged) |" in strips_learned_objects.markdown(result)


def test_a_bundle_among_the_models_reports_the_share_routed_to_the_familys_own_specialist(tmp_path: Path) -> None:
    suite = two_families()
    hidden = 4
    arrays = {  # a router that sends every frame to bottle_cap: its last layer's weights zero, its bias large
        "mean": np.zeros(33),
        "std": np.ones(33),
        "w0": np.zeros((hidden, 33)),
        "b0": np.zeros(hidden),
        "w1": np.zeros((hidden, hidden)),
        "b1": np.zeros(hidden),
        "w2": np.zeros((2, hidden)),
        "b2": np.array([10.0, 0.0]),
    }
    bundle = bundle_folder(tmp_path / "bundle", arrays, accept=0.9, stand_ins={"bottle_cap": "strips16_small"}).parent
    result = strips_learned_objects.judge(suite, None, [str(bundle)], None, [3], 6, log=lambda _: None)
    routed = {fam: f["routed_to_own"] for fam, f in result["families"].items()}
    assert routed == {"bottle_cap": {str(bundle): 1.0}, "five_fingertips": {str(bundle): 0.0}}
