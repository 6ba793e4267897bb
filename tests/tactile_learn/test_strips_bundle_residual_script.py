"""scripts/strips_bundle_residual.py: per family, the frames a bundle sends to a specialist, with the
specialist's and the default's r and readings residual on exactly those frames."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from synth.suite import load_suite
from tactile_learn.known_objects import DEFAULT, KnownObjects
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.strips_consistency import StripConsistency
from tactile_learn.suites import suite_eval_data
from tests.paths import REPO_ROOT
from tests.tactile_learn.test_known_objects import STAND_INS, bundle_folder, random_router

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_bundle_residual

SUITE = "strips16_unseen4"


def test_the_figures_recompute_on_the_frames_sent(tmp_path: Path) -> None:
    path = bundle_folder(tmp_path / "b", random_router(3, seed=1))
    out = tmp_path / "res.json"
    argv = [str(path), "--unknown", SUITE, "--n", "8", "--seed", "4", "--json", str(out)]
    assert strips_bundle_residual.main(argv) == 0
    result = json.loads(out.read_text())
    assert out.with_suffix(".md").read_text().startswith("# Frames a bundle sends to a specialist")
    bundle = KnownObjects(path).prepare()
    scene = load_suite(SUITE).base
    consistency = StripConsistency(scene)
    default = resolve_method("strips", "strips16", scene)
    rows = {row["family"]: row for row in result["rows"]}
    checked = 0
    for family, data in suite_eval_data(load_suite(SUITE), 8, 4).items():
        names = bundle.route(data.inputs)
        sent = names != DEFAULT
        if not sent.any():
            assert family not in rows
            continue
        row = rows[family]
        assert row["sent"] == int(sent.sum()) and row["known"] is False
        x, truth = data.inputs[sent], data.truth["pressure"][sent]
        spec = np.concatenate(
            [
                resolve_method("strips", STAND_INS[str(n)], scene).predict(x[i : i + 1])
                for i, n in enumerate(names[sent])
            ]
        )
        base = default.predict(x)
        gain = np.nanmean(np.asarray(pearson_per_frame(spec, truth)) - np.asarray(pearson_per_frame(base, truth)))
        assert row["r_gain"] == pytest.approx(gain, abs=1e-5)
        ratio = consistency.residual(x, spec)["residual_rel"] / consistency.residual(x, base)["residual_rel"]
        assert row["residual_ratio"] == pytest.approx(float(np.median(ratio)), rel=1e-3)
        checked += 1
    assert checked > 0


def test_no_suite_is_refused() -> None:
    with pytest.raises(SystemExit, match="give --known or --unknown"):
        strips_bundle_residual.main(["somewhere"])
