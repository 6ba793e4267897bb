"""Every shipped model still meets its card: fresh held-out frames (a seed no card used) are
simulated for the scene the card's held-out figures were measured on (the card's own where the entry
names none), and the ONNX model's metrics are compared with the card's."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from synth.dataset import generate
from synth.scene import load_scene, parse_scene
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.tasks import get_task
from tests.paths import REPO_ROOT

MODELS = sorted((REPO_ROOT / "models").glob("*.onnx"))
FRESH_SEED = 424242
#: per task: frames to simulate, and (metric, higher is better, allowed slack) checked against the card;
#: the slack covers the sampling error of a small fresh set, not a loss of accuracy
CHECKS = {
    "strips": (600, [("pearson_r_mean", True, 0.015), ("nrmse", False, 0.04)]),
    "fsr": (3000, [("force_accuracy", True, 0.02), ("loc_err_mm_median", False, 0.15)]),
    "thermal": (60, [("accuracy", True, 0.06)]),
    "capacitive": (100, [("iou_mean", True, 0.02), ("centroid_err_mm_median", False, 0.02)]),
}


@pytest.mark.parametrize("model", MODELS, ids=[m.stem for m in MODELS])
def test_shipped_model_meets_its_card(model: Path, tmp_path: Path) -> None:
    card = json.loads(model.with_suffix(".json").read_text())
    assert model.stat().st_size < 5 * 2**20, "shipped models stay well under 5 MB"
    heldout = card["metrics"]["heldout"]
    assert heldout["command"].startswith("tactile-learn ") and heldout["data"]["seed"] != FRESH_SEED
    # the held-out set's scene: a routed member's card names its training scene (for the strips16 sensor, a
    # script-drawn set's placeholder), and its figures were measured on the library's held-out scene
    held = heldout["data"].get("scene")
    scene = load_scene(held) if held is not None else parse_scene(card["scene"])
    assert scene.digest == heldout["data"].get("scene_digest", scene.digest)
    n, checks = CHECKS[card["task"]]
    generate(scene, n, FRESH_SEED, tmp_path / "fresh")
    task = get_task(card["task"])
    metrics = task.evaluate(OnnxEstimator(model), task.load_eval_data(tmp_path / "fresh"))
    for name, higher_better, slack in checks:
        claimed = heldout["values"][name]
        if higher_better:
            assert metrics[name] >= claimed - slack, (name, metrics[name], claimed)
        else:
            assert metrics[name] <= claimed + slack, (name, metrics[name], claimed)
