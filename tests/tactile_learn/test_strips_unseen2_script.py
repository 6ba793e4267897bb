"""scripts/strips_unseen.py and strips_unseen_probe.py on round 2 (strips16_unseen2): a model
without a readings residual (strips16_spheres) gets r, NRMSE and its margin but no flag figures;
probe ladders set an object's parameter, keep the rest and apply their fixed settings."""

from __future__ import annotations

import sys

import numpy as np

from synth.scene import read_toml
from synth.suite import parse_suite
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.suites import suite_eval_data
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_unseen
import strips_unseen_probe

SPHERES = str(REPO_ROOT / "models" / "strips16_spheres.onnx")
GENERAL = str(REPO_ROOT / "models" / "strips16_small.onnx")


def test_a_model_without_a_residual_gets_its_margin_and_no_flag() -> None:
    data, _ = read_toml("strips16_unseen2", "suites", "suite")
    suite = parse_suite({**data, "families": [f for f in data["families"] if f["name"] == "coin_off_centre"]}, "one")
    result = strips_unseen.evaluate(suite, [SPHERES, GENERAL], n=10, seeds=[5], log=lambda _: None)
    assert set(result["thresholds"]) == {GENERAL}
    row = result["per_seed"]["5"]["coin_off_centre"]
    frames = suite_eval_data(suite, 10, 5)["coin_off_centre"]
    truth = frames.truth["pressure"]
    r = {
        m: np.nanmean(pearson_per_frame(resolve_method("strips", m, suite.base).predict(frames.inputs), truth))
        for m in ("intersection", "projection", SPHERES)
    }
    assert np.isclose(row["models"][SPHERES]["margin"], r[SPHERES] - max(r["intersection"], r["projection"]))
    assert "flagged_share" not in row["models"][SPHERES] and "flagged_share" in row["models"][GENERAL]
    table = strips_unseen.markdown({**result, "command": "x"}, [SPHERES, GENERAL])
    header = next(line for line in table.splitlines() if "flagged, losing" in line)
    assert GENERAL in header and SPHERES not in header


def test_object_probes_set_the_object_and_their_fixed_settings() -> None:
    suite_name, family, parameter, values, fixed = strips_unseen_probe.PROBES["pair_turn"]
    assert suite_name == "strips16_unseen2" and parameter == "object.rotation_deg"
    suite = parse_suite(strips_unseen_probe.probe_suite("pair_turn"), "probe")
    original = parse_suite(read_toml(suite_name, "suites", "suite")[0], "x").family(family).scene.sensor.stimuli
    assert len(suite.families) == len(values)
    for fam, value in zip(suite.families, values, strict=True):
        stimuli = fam.scene.sensor.stimuli
        assert stimuli.object is not None and stimuli.object.rotation_deg == (value, value)
        assert stimuli.object.offsets_mm == original.object.offsets_mm  # type: ignore[union-attr]
        assert stimuli.count == (fixed["count"], fixed["count"]) and stimuli.kinds == original.kinds
    tilts = parse_suite(strips_unseen_probe.probe_suite("coin_tilt"), "probe").families
    assert [f.scene.sensor.stimuli.kinds[0].tilt for f in tilts] == [(v, v) for v in (0.0, 0.25, 0.5, 0.75, 1.0)]


def test_near_l_share_counts_ls_of_shared_rows_and_columns() -> None:
    """Three studs square to the strips (within 5 degrees: 0.7 mm off over an 8 mm arm) are an L in
    every frame; two studs never are; turned 45 degrees, three studs are a diamond's corner, no L."""
    data, _ = read_toml("strips16_unseen2", "suites", "suite")
    square = next(f for f in data["families"] if f["name"] == "lego_2x2_square")

    def share(count: int, rotation: float) -> float:
        fam = {**square, "strips": {"stimuli": {**square["strips"]["stimuli"], "count": [count, count]}}}
        fam["strips"]["stimuli"]["object"] = {**square["strips"]["stimuli"]["object"], "rotation_deg": [rotation] * 2}
        scene = parse_suite({**data, "families": [fam]}, "one").families[0].scene
        return strips_unseen_probe.near_l_share(scene, 200, seed=1)

    assert share(3, 5.0) == 1.0 and share(4, 0.0) == 1.0
    assert share(2, 0.0) == 0.0 and share(3, 45.0) == 0.0
