"""Issue 11's protocol on the real robot recordings (../shared/data/thermal-robot, or the folder in
$TACTILE_THERMAL_ROBOT): label the 9 touches of session R_1, adapt, classify the 81 touches of
R_2..R_10, and hold the floors: heated + passive >= 98 % at 2 s of contact (the network and the
classifier adapt chose), heated only >= 90 % at 4 s (held by the press-aligned nearest-touch
classifier trained on the 9 labelled touches: the network adapted on the heated channel alone stays
at 0.67, see docs/thermal-real.md). Skipped, saying why, only where the recordings are absent."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import pytest

from synth.config import replace
from tactile_learn.few_shot import few_shot_predict
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.tasks.thermal import ThermalTask
from tactile_learn.thermal_adapt import adapt_scene, calibrate_recordings
from tactile_learn.thermal_choice import choice_evaluate, load_adapted
from tactile_learn.thermal_recordings import select_recordings
from tests.paths import REPO_ROOT

ROOT = REPO_ROOT
DATA = Path(os.environ.get("TACTILE_THERMAL_ROBOT") or ROOT.parent / "shared" / "data" / "thermal-robot")
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        not (DATA / "touches.csv").is_file(),
        reason=f"the thermal-robot recordings are not at {DATA} (set TACTILE_THERMAL_ROBOT to their folder)",
    ),
]
#: the test's training budget: adapt's default
N_TRAIN, EPOCHS = 16000, 12


@pytest.fixture(scope="module")
def protocol(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    work = tmp_path_factory.mktemp("robot")
    labelled = select_recordings(DATA, work / "labelled", "session", ["R_1"])
    test = select_recordings(DATA, work / "test", "session", ["R_1"], keep=False)
    scene, report = calibrate_recordings(labelled, ("heated", "passive"))
    task = ThermalTask()
    out: dict[str, Any] = {"report": report}
    adapt_scene(scene, report, labelled, work / "all", channels="all", n_train=N_TRAIN, epochs=EPOCHS)
    model = OnnxEstimator(work / "all" / "model.onnx")
    data = task.load_eval_data(test, model.card_scene_)
    out["all"] = task.evaluate(model, data, durations=(0.5, 1.0, 2.0, 4.0), group_by="condition")
    out["n_all"] = len(data)
    # what the user classifies with: adapt's choice (tactile-learn eval --method FOLDER/)
    adapted = load_adapted(work / "all")
    assert adapted is not None
    kept = task.load_eval_data(adapted[1], model.card_scene_)
    out["choice"] = choice_evaluate(kept, data, adapted[0], durations=(2.0, 4.0), group_by="condition")
    # heated only: the classifier trained on the 9 labelled touches, read against press time
    heated = dataclasses.replace(scene, sensor=replace(scene.sensor, "channels", ["heated"]))
    train, data = task.load_eval_data(labelled, heated), task.load_eval_data(test, heated)
    out["heated"] = {"n": len(data), "truth": data.truth["label"], "condition": data.extra["info:condition"]}
    for d in (2.0, 4.0):
        out["heated"][d] = few_shot_predict("press_aligned", train, data, d).argmax(axis=1)
    return out


def test_heated_and_passive_floor(protocol: dict[str, Any]) -> None:
    assert protocol["n_all"] == 81
    accuracy = protocol["all"]["accuracy_by_duration"]
    assert accuracy["2.0"] >= 0.98, accuracy
    assert accuracy["4.0"] >= 0.98, accuracy


def test_adapt_choice_holds_the_heated_and_passive_floor(protocol: dict[str, Any]) -> None:
    accuracy = protocol["choice"]["accuracy_by_duration"]
    assert accuracy["2.0"] >= 0.98 and accuracy["4.0"] >= 0.98, protocol["choice"]["choice_by_duration"]
    for condition in ("M", "W", "CW"):
        assert protocol["choice"]["by_group"][condition]["accuracy_by_duration"]["2.0"] >= 0.95, condition


def test_heated_only_floor(protocol: dict[str, Any]) -> None:
    heated = protocol["heated"]
    assert heated["n"] == 81
    right = heated[4.0] == heated["truth"]
    by_condition = {c: float(right[heated["condition"] == c].mean()) for c in ("M", "W", "CW")}
    assert right.mean() >= 0.90, by_condition
    # not by answering one class: metal and cooled wood, the pair the heated curve hardly tells apart
    assert min(by_condition.values()) >= 0.75, by_condition


def test_calibration_report_of_r1_is_complete(protocol: dict[str, Any]) -> None:
    report = protocol["report"]
    assert report["channels_fitted"] == ["heated", "passive"]
    assert len(report["touches"]) == 9 and {t["onset_from"] for t in report["touches"]} == {"force"}
    for entry in report["parameters"].values():
        assert {"value", "unit", "bounds"} <= set(entry)
    # every parameter at a bound is listed, and the residual is given in kelvin and in noise sigma
    assert set(report["at_bound"]) == {k for k, v in report["parameters"].items() if "at_bound" in v}
    assert report["residual"]["rms_k"] < 0.05 and report["residual"]["rms_sigma"] > 0
