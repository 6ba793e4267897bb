"""scripts/strips_family_data.py and strips_specialists.py on a few frames: the dataset holds exactly the
family's frames (the same bytes the suite's family draws at that seed), an unknown family or a malformed
entry is refused naming the problem, and the specialists' table recomputes from the frames it names."""

from __future__ import annotations

import dataclasses
import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from synth.dataset import Dataset, simulate_shard
from synth.errors import ConfigError
from synth.suite import load_suite
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.suites import suite_eval_data
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_family_data
import strips_specialists

SUITE = "strips16_unseen4"
FAMILY = "card_corner"
MODEL = "strips16_small"


def test_family_data_is_the_familys_frames(tmp_path: Path) -> None:
    out = tmp_path / "fam"
    argv = ["--suite", SUITE, "--family", FAMILY, "--n", "7", "--seed", "5", "--out", str(out)]
    assert strips_family_data.main(argv) == 0
    data = Dataset(out)
    assert len(data) == 7
    expected = simulate_shard(load_suite(SUITE).family(FAMILY).scene, 5, 0, 7)
    written = data.arrays()
    assert set(written) == set(expected)
    for key, values in expected.items():
        np.testing.assert_array_equal(written[key], values, err_msg=key)
    other = simulate_shard(load_suite(SUITE).family("bead_loop").scene, 5, 0, 7)
    assert not np.array_equal(other["readings"], expected["readings"])


def test_an_unknown_family_is_refused_listing_the_families(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"no family 'teapot'.*card_corner"):
        strips_family_data.write_family(SUITE, "teapot", 3, 1, tmp_path / "x")


@pytest.mark.parametrize("entry", ["strips16_unseen4:bead_loop", "bead_loop=m.onnx", ":bead_loop=m.onnx"])
def test_a_malformed_entry_is_refused_naming_the_form(entry: str) -> None:
    with pytest.raises(ConfigError, match="SUITE:FAMILY=MODEL"):
        strips_specialists.parse_entry(entry)


def test_the_specialists_margins_recompute_from_the_frames(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    model = str(run / "model.onnx")  # a stand-in specialist: the small shipped model as a run exports it
    shutil.copyfile(REPO_ROOT / "models" / f"{MODEL}.onnx", model)
    shutil.copyfile(REPO_ROOT / "models" / f"{MODEL}.json", run / "model.json")
    out = tmp_path / "spec.json"
    argv = [f"{SUITE}:{FAMILY}={model}", "--default", "strips16", "--n", "10", "--seeds", "3", "--json", str(out)]
    assert strips_specialists.main(argv) == 0
    result = json.loads(out.read_text())
    fam = result["families"][FAMILY]
    suite = load_suite(SUITE)
    frames = suite_eval_data(dataclasses.replace(suite, families=(suite.family(FAMILY),)), 10, 3)[FAMILY]
    truth = frames.truth["pressure"]
    r = {
        m: float(np.nanmean(pearson_per_frame(resolve_method("strips", m, suite.base).predict(frames.inputs), truth)))
        for m in ("intersection", "projection", "strips16", model)
    }
    best = max(r["intersection"], r["projection"])
    for m, value in r.items():
        assert np.isclose(fam["r"][m], value), m
    assert np.isclose(fam["margin"][model], r[model] - best)
    assert np.isclose(fam["margin"]["strips16"], r["strips16"] - best)
    assert fam["verdict"][model] == strips_specialists.verdict(r[model] - best)
    assert np.isclose(result["mean_margin"]["best_specialist"], r[model] - best)
    card = json.loads((run / "model.json").read_text())["metrics"]["heldout"]
    assert fam["heldout"][model]["r"] == card["values"]["pearson_r_mean"]
    assert fam["heldout"][model]["seed"] == card["data"]["seed"]
    assert FAMILY in out.with_suffix(".md").read_text()


def test_the_verdict_follows_the_floor() -> None:
    floor = strips_specialists.PRIOR_MARGIN
    assert strips_specialists.verdict(floor).startswith("prior")
    assert strips_specialists.verdict(floor / 2).startswith("small gain")
    assert strips_specialists.verdict(-0.01).startswith("information limit")
