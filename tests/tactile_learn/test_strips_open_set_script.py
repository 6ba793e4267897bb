"""scripts/strips_open_set.py: the threshold routes at most the asked share of unknown frames; the figures
recompute from the suites' frames (the default's margins, and the routed path at all or none of the frames
routed). The routing rule itself is tactile_learn.known_objects.choose (tests/tactile_learn/test_known_objects.py)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from synth.suite import load_suite
from tactile_learn.known_objects import choose
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.suites import suite_eval_data
from tactile_learn.tasks.base import EvalData
from tests.paths import REPO_ROOT
from tests.tactile_learn.test_strips_known_objects_script import MODEL, stand_in_specialist

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_family_data
import strips_open_set

SUITE = "strips16_unseen4"
KNOWN = ("card_corner", "bead_loop")
OTHER = "ruler_edge"
OPEN_SUITE = "strips16_unseen3"


def test_the_threshold_routes_at_most_the_asked_share_of_unknown_frames() -> None:
    rng = np.random.default_rng(4)
    logits = rng.normal(size=(1000, 4)) * 3
    prob = np.exp(logits) / np.exp(logits).sum(axis=1, keepdims=True)
    for share in (0.0, 0.01, 0.2, 0.6):
        accept = strips_open_set.accept_on(prob, 3, share)
        assert accept >= 0.5
        assert np.mean(choose(prob, 3, accept) < 3) <= share
    # at least 0.5 even when more than half of the frames could be routed
    assert strips_open_set.accept_on(prob, 3, 0.99) == 0.5
    with pytest.raises(SystemExit, match="false share must be in"):
        strips_open_set.accept_on(prob, 3, 1.0)


def test_the_figures_recompute_from_the_frames(tmp_path: Path) -> None:
    models = []
    for i, family in enumerate(KNOWN):
        data = tmp_path / f"data-{family}"
        strips_family_data.write_family(SUITE, family, 40, 70 + i, data)
        models.append(stand_in_specialist(tmp_path / family, family, data))
    other = tmp_path / "other"
    strips_family_data.write_family(SUITE, OTHER, 60, 80, other)
    out = tmp_path / "open.json"
    argv = [*models, "--suite", SUITE, "--open-suites", OPEN_SUITE, "--other", str(other), "--train-frames", "40"]
    argv += ["--other-frames", "40", "--val-frames", "20", "--n", "10", "--seeds", "3", "--json", str(out)]
    assert strips_open_set.main(argv) == 0
    result = json.loads(out.read_text())
    assert out.with_suffix(".md").read_text().startswith("# Known objects among unknown ones")
    checked = {"all routed": 0, "none routed": 0}
    for suite_name in (SUITE, OPEN_SUITE):
        suite = load_suite(suite_name)
        frames = suite_eval_data(suite, 10, 3)
        judged = [f for f in frames if suite_name != SUITE or f in KNOWN]
        r = {f: mean_r(suite_name, frames[f]) for f in judged[:2]}
        for router, rows in result["routers"].items():
            assert sum(row["chosen"] for row in rows) == 1, router
            for row in rows:
                families = row["suites"][suite_name]["families"]
                assert sorted(families) == sorted(judged)
                for family, rf in r.items():
                    best = max(rf["intersection"], rf["projection"])
                    fam = families[family]
                    assert np.isclose(fam["default"], rf["strips16"] - best)
                    # every specialist is the same network: all frames routed give its r, none the default's
                    if fam["to_specialist"] == 1.0:
                        assert np.isclose(fam["routed"], rf[MODEL] - best)
                        checked["all routed"] += 1
                    if fam["to_specialist"] == 0.0:
                        assert np.isclose(fam["routed"], fam["default"])
                        checked["none routed"] += 1
                    assert ("right_share" in fam) == (suite_name == SUITE)
    assert min(checked.values()) > 0, checked


def mean_r(suite_name: str, data: EvalData) -> dict[str, float]:
    base = load_suite(suite_name).base
    return {
        m: float(
            np.nanmean(
                pearson_per_frame(resolve_method("strips", m, base).predict(data.inputs), data.truth["pressure"])
            )
        )
        for m in ("intersection", "projection", "strips16", MODEL)
    }
