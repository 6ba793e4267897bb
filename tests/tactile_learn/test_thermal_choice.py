"""adapt's classifier choice (tactile_learn.thermal_choice): candidates scored on the labelled
touches, the best averaged; the labelled touches kept in the adapt folder; eval with the folder."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from synth.config import replace
from synth.errors import ConfigError, DataError
from tactile_learn.few_shot import few_shot_predict, leave_one_out
from tactile_learn.tasks.thermal import ThermalTask
from tactile_learn.tasks.thermal_data import view
from tactile_learn.thermal_choice import (
    candidate_scores,
    choice_evaluate,
    choice_predict,
    choose,
    copy_recordings,
    load_adapted,
    write_choice,
)
from tactile_learn.thermal_recordings import write_recordings
from tests.tactile_learn.test_thermal_real import robot_scene, robot_touches

TASK = ThermalTask()


class ConstantNetwork:
    """A stand-in network that answers the same probabilities (classes + "no contact") for every window."""

    def __init__(self, proba: list[float]) -> None:
        self.proba = np.asarray(proba)
        self.calls = 0

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        self.calls += 1
        return np.tile(self.proba, (len(x), 1))


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    folder = tmp_path_factory.mktemp("choice")
    write_recordings(folder / "train", robot_touches(9, 5))
    write_recordings(folder / "test", robot_touches(12, 6))
    scene = robot_scene()
    heated = dataclasses.replace(scene, sensor=replace(scene.sensor, "channels", ["heated"]))  # type: ignore[arg-type]
    return {
        "folder": folder,
        "train": TASK.load_eval_data(folder / "train", heated),
        "test": TASK.load_eval_data(folder / "test", heated),
    }


def test_choose_keeps_every_candidate_within_one_labelled_touch_of_the_best() -> None:
    scores = {"network": 1.0, "press_aligned": 8 / 9, "aligned_pca": 7 / 9}
    assert choose(scores, 9) == ["network", "press_aligned"]
    assert choose(scores, 4) == ["network", "press_aligned", "aligned_pca"]  # one touch in 4 is 0.25
    assert choose({"network": 0.5, "press_aligned": 1.0, "aligned_pca": 2 / 3}, 9) == ["press_aligned"]
    # a difference of exactly one touch, computed two ways, is within it
    assert choose({"a": 1 - 2 / 9, "b": 6 / 9}, 9) == ["a", "b"]
    with pytest.raises(ConfigError, match="no candidate"):
        choose({}, 9)
    with pytest.raises(ConfigError, match="labelled touches"):
        choose(scores, 0)


def test_candidate_scores_are_leave_one_out_and_the_network_on_the_labelled_touches(
    recordings: dict[str, object],
) -> None:
    train = recordings["train"]
    labels = train.truth["label"]  # type: ignore[attr-defined]
    always_metal = ConstantNetwork([0.9, 0.1, 0.0])  # class 0 is metal
    scores = candidate_scores(train, always_metal, 4.0)  # type: ignore[arg-type]
    assert list(scores) == ["network", "calibrated", "aligned_pca", "press_aligned"]
    assert scores["network"] == pytest.approx(np.mean(labels == 0))
    for method in ("aligned_pca", "press_aligned"):
        assert scores[method] == pytest.approx(leave_one_out(method, train, 4.0))  # type: ignore[arg-type]
    # the calibrated model: the classical method's own answers on the labelled touches
    calibrated = TASK.classical_methods()["calibrated"](train.scene)  # type: ignore[attr-defined]
    x, _ = view(train, 4.0)  # type: ignore[arg-type]
    right = calibrated.predict_proba(x)[:, :2].argmax(axis=1) == labels  # type: ignore[attr-defined]
    assert scores["calibrated"] == pytest.approx(right.mean())
    assert set(candidate_scores(train, None, 4.0)) == {"calibrated", "aligned_pca", "press_aligned"}  # type: ignore[arg-type]


def test_choice_predict_is_a_vote_with_ties_to_the_mean_probability(recordings: dict[str, object]) -> None:
    train, test = recordings["train"], recordings["test"]
    metal = ConstantNetwork([0.6, 0.2, 0.2])  # its "no contact" column is dropped, the rest renormalised
    alone = choice_predict(["network"], train, test, 2.0, metal)  # type: ignore[arg-type]
    assert (alone.argmax(axis=1) == 0).all()
    np.testing.assert_allclose(alone, np.tile([(1 + 0.75) / 2, 0.25 / 2], (len(alone), 1)))
    few = {m: few_shot_predict(m, train, test, 2.0) for m in ("press_aligned", "aligned_pca")}  # type: ignore[arg-type]
    # three members: the majority of their answers, whatever the confidence of the one outvoted
    sure_wood = ConstantNetwork([0.0, 1.0, 0.0])
    three = choice_predict(["network", "press_aligned", "aligned_pca"], train, test, 2.0, sure_wood)  # type: ignore[arg-type]
    votes = 1 + sum((p.argmax(axis=1) == 1).astype(int) for p in few.values())  # votes for wood (class 1)
    np.testing.assert_array_equal(three.argmax(axis=1), (votes >= 2).astype(int))
    np.testing.assert_allclose(three.sum(axis=1), 1.0)
    # two members that disagree: the class of the higher mean probability
    two = choice_predict(["network", "press_aligned"], train, test, 2.0, metal)  # type: ignore[arg-type]
    mean = 0.5 * (np.tile([0.75, 0.25], (len(alone), 1)) + few["press_aligned"])
    np.testing.assert_array_equal(two.argmax(axis=1), mean.argmax(axis=1))
    with pytest.raises(ConfigError, match="not available"):
        choice_predict(["network"], train, test, 2.0, None)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="no member"):
        choice_predict([], train, test, 2.0, None)  # type: ignore[arg-type]


def test_choice_evaluate_follows_the_labelled_touches(recordings: dict[str, object]) -> None:
    """The metrics are those of the members the labelled touches chose, per duration."""
    train, test = recordings["train"], recordings["test"]
    network = ConstantNetwork([0.9, 0.1, 0.0])
    metrics = choice_evaluate(train, test, network, (1.0, 4.0), "condition")  # type: ignore[arg-type]
    for key in ("1.0", "4.0"):
        choice = metrics["choice_by_duration"][key]
        assert choice["members"] == choose(choice["scores"], 9)
        proba = choice_predict(choice["members"], train, test, float(key), network)  # type: ignore[arg-type]
        expected = float(np.mean(proba.argmax(axis=1) == test.truth["label"]))  # type: ignore[attr-defined]
        assert metrics["accuracy_by_duration"][key] == pytest.approx(expected)
    assert set(metrics["by_group"]) == {"cold", "room"}
    assert network.calls > 0


def test_copy_recordings_is_self_contained_and_names_its_problems(
    recordings: dict[str, object], tmp_path: Path
) -> None:
    source = tmp_path / "src"
    shutil.copytree(recordings["folder"] / "train", source)  # type: ignore[operator]
    copy = copy_recordings(source, tmp_path / "kept")
    shutil.rmtree(source)  # the copy must not depend on the original
    scene = recordings["train"].scene  # type: ignore[attr-defined]
    again = TASK.load_eval_data(copy, scene)
    np.testing.assert_array_equal(again.extra["record"], recordings["train"].extra["record"])  # type: ignore[attr-defined]
    np.testing.assert_array_equal(again.truth["label"], recordings["train"].truth["label"])  # type: ignore[attr-defined]
    with pytest.raises(DataError, match=r"no touches\.csv"):
        copy_recordings(tmp_path / "nothing", tmp_path / "k2")
    broken = tmp_path / "broken"
    shutil.copytree(copy, broken)
    (broken / "t0.csv").unlink()
    with pytest.raises(DataError, match=r"t0\.csv"):
        copy_recordings(broken, tmp_path / "k3")
    assert load_adapted(tmp_path / "nothing") is None and load_adapted("press_aligned") is None


def test_adapt_writes_its_choice_and_eval_classifies_with_the_folder(tmp_path: Path) -> None:
    """A tiny adapt after its calibration (the pipeline, not the accuracy): the card holds the
    choice per duration and the labelled touches are kept; eval with the folder as --method redoes
    the same choice and reports it; the network alone stays reachable as FOLDER/model.onnx."""
    from tactile_learn.cli import main
    from tactile_learn.thermal_adapt import adapt_scene

    write_recordings(tmp_path / "rec", robot_touches(6, 21))
    write_recordings(tmp_path / "more", robot_touches(8, 22))
    out = tmp_path / "adapted"
    # the simulator's own scene stands in for a calibration (tested with adapt in test_thermal_real)
    report = {"residual": {"rms_k": 1e-3, "rms_sigma": 2.0}, "solver": {"seconds": 0.0}}
    adapt_scene(robot_scene(), report, tmp_path / "rec", out, channels="heated", n_train=256, n_val=64, epochs=1)
    card = json.loads((out / "model.json").read_text())
    assert card["adapt"]["timings_s"]["choose_s"] >= 0 and isinstance(card["warnings"], list)
    choice = card["classifier"]
    assert choice["n_labelled"] == 6 and set(choice["by_duration"]) == {"0.25", "0.5", "1.0", "2.0", "4.0"}
    for entry in choice["by_duration"].values():
        assert set(entry["scores"]) == {"network", "calibrated", "aligned_pca", "press_aligned"}
        assert entry["members"] == choose(entry["scores"], 6)
    assert (out / choice["labelled"] / "touches.csv").is_file()
    shutil.rmtree(tmp_path / "rec")  # the folder carries what the choice needs
    evaluate = ["eval", "--task", "thermal", "--data", str(tmp_path / "more"), "--durations", "1,4"]
    assert main([*evaluate, "--method", str(out), "--group-by", "condition", "--json", str(tmp_path / "c.json")]) == 0
    result = json.loads((tmp_path / "c.json").read_text())
    assert result["method"].endswith("(adapt's choice)") and result["n_frames"] == 8
    for key in ("1.0", "4.0"):
        assert result["metrics"]["choice_by_duration"][key] == choice["by_duration"][key]
    assert set(result["metrics"]["by_group"]) <= {"cold", "room"}
    assert main([*evaluate, "--method", str(out / "model.onnx"), "--json", str(tmp_path / "n.json")]) == 0
    assert "choice_by_duration" not in json.loads((tmp_path / "n.json").read_text())["metrics"]
    # a card without a choice (an older adapt) is named as such
    del card["classifier"]
    (out / "model.json").write_text(json.dumps(card))
    with pytest.raises(ConfigError, match="no classifier choice"):
        load_adapted(out)


def test_write_choice_keeps_the_durations_the_labelled_records_reach(tmp_path: Path) -> None:
    """Records cut 4.5 s after their start (onsets near 3 s): none reaches 2 s of contact, so the card
    holds only the shorter durations (adapt does not fail after training)."""
    short = []
    for touch in robot_touches(6, 31):
        end = int(np.searchsorted(touch.time_s, 4.5))
        cut = {k: getattr(touch, k)[:end] for k in ("time_s", "temperature_c", "passive_c", "force")}
        short.append(dataclasses.replace(touch, **cut))
    write_recordings(tmp_path / "short", short)
    scene = robot_scene()
    heated = dataclasses.replace(scene, sensor=replace(scene.sensor, "channels", ["heated"]))  # type: ignore[arg-type]
    choice = write_choice(ConstantNetwork([0.5, 0.5, 0.0]), tmp_path / "short", tmp_path / "out", heated)
    reached = set(choice["by_duration"])
    assert reached and "4.0" not in reached and "2.0" not in reached
    assert reached <= {"0.25", "0.5", "1.0"}
    assert (tmp_path / "out" / "labelled" / "touches.csv").is_file()
