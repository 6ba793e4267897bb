"""`tactile-learn cards verify`: a card's held-out metrics regenerated and re-measured."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from synth.dataset import generate
from synth.io import atomic_write_json
from synth.scene import load_scene
from tactile_learn.cards import compare_values, verify_card
from tactile_learn.cli import main
from tactile_learn.methods import resolve_method
from tactile_learn.provenance import dataset_record
from tactile_learn.tasks import get_task

MODELS = Path(__file__).resolve().parents[2] / "models"


def test_compare_values_passes_equal_figures_and_names_each_one_that_moved() -> None:
    recorded = {"r": 0.5, "by": {"a": [1, 2.0]}, "label": "x", "none": None}
    assert all(row["ok"] for row in compare_values(recorded, json.loads(json.dumps(recorded))))
    now = {"r": 0.5 + 1e-4, "by": {"a": [1, 2.0 + 1e-7]}, "label": "y"}
    rows = {row["key"]: row for row in compare_values(recorded, now)}
    assert not rows["r"]["ok"] and rows["r"]["match"] == "differs" and rows["r"]["now"] == pytest.approx(0.5 + 1e-4)
    assert rows["by.a[0]"]["match"] == "exact" and rows["by.a[1]"]["match"] == "close"
    assert not rows["label"]["ok"]
    assert rows["none"]["match"] == "missing"  # no longer reported: a figure that vanished is a difference
    assert compare_values({"r": 0.5}, {"r": 0.5 + 1e-4}, rtol=1e-3)[0]["ok"]
    assert not compare_values({"r": 0.5}, {"r": 0.5 + 1e-9}, rtol=0)[0]["ok"]
    # NaN now is what a card records as null (strict JSON)
    assert compare_values({"r": None}, {"r": float("nan")})[0]["match"] == "exact"


@pytest.fixture()
def small_card(tmp_path: Path) -> Path:
    """The shipped strips5 model with a card whose held-out set is 64 frames of seed 3, measured now."""
    model = tmp_path / "strips5.onnx"
    shutil.copy(MODELS / "strips5.onnx", model)
    shutil.copy(MODELS / "strips5.json", model.with_suffix(".json"))
    card = json.loads((MODELS / "strips5.json").read_text())
    data_dir = tmp_path / "test-data"
    generate(load_scene("strips5"), 64, 3, data_dir)
    task = get_task("strips")
    data = task.load_eval_data(data_dir)
    values = task.evaluate(resolve_method("strips", str(model), data.scene), data)
    card["metrics"] = {"validation": {}, "heldout": {"data": dataset_record(data_dir, len(data)), "values": values}}
    atomic_write_json(model.with_suffix(".json"), card)
    shutil.rmtree(data_dir)  # verify regenerates it from the card alone
    return model


def test_a_card_measured_on_the_same_seed_verifies_exactly(small_card: Path, tmp_path: Path) -> None:
    report = verify_card(small_card, workdir=tmp_path / "work")
    assert report["ok"], report["sets"]["heldout"]["differ"]
    assert report["sets"]["heldout"]["n_checked"] > 5
    assert report["sets"]["heldout"]["n_exact"] == report["sets"]["heldout"]["n_checked"]


def test_a_changed_figure_fails_and_is_named(small_card: Path, tmp_path: Path) -> None:
    card_file = small_card.with_suffix(".json")
    card = json.loads(card_file.read_text())
    card["metrics"]["heldout"]["values"]["nrmse"] *= 1.001
    atomic_write_json(card_file, card)
    report = verify_card(small_card, workdir=tmp_path / "work")
    differ = report["sets"]["heldout"]["differ"]
    assert not report["ok"] and [row["key"] for row in differ] == ["values.nrmse"]
    assert main(["cards", "verify", "--model", str(small_card)]) == 1


def test_a_card_that_does_not_name_its_data_scene_says_so(small_card: Path) -> None:
    card_file = small_card.with_suffix(".json")
    card = json.loads(card_file.read_text())
    del card["metrics"]["heldout"]["data"]["scene"]
    atomic_write_json(card_file, card)
    result = verify_card(small_card)["sets"]["heldout"]
    assert not result["ok"] and "does not record its scene" in result["error"]


def test_an_unknown_set_name_is_an_error(small_card: Path) -> None:
    assert main(["cards", "verify", "--model", str(small_card), "--set", "nope"]) == 2


def test_cards_add_records_a_dataset_entry_that_verify_then_reproduces(tmp_path: Path) -> None:
    model = tmp_path / "strips5.onnx"
    shutil.copy(MODELS / "strips5.onnx", model)
    shutil.copy(MODELS / "strips5.json", model.with_suffix(".json"))
    data_dir = tmp_path / "more"
    generate(load_scene("strips5"), 32, 9, data_dir)
    assert main(["cards", "add", "--model", str(model), "--name", "more", "--data", str(data_dir)]) == 0
    entry = json.loads(model.with_suffix(".json").read_text())["metrics"]["more"]
    assert entry["data"]["scene"] == "strips5" and entry["data"]["seed"] == 9 and entry["data"]["n"] == 32
    assert entry["command"].startswith("tactile-learn cards add") and 0.9 < entry["values"]["pearson_r_mean"] <= 1
    shutil.rmtree(data_dir)
    assert verify_card(model, names=["more"], rtol=0)["ok"]


def test_cards_add_refuses_two_sources_or_the_validation_key(small_card: Path, tmp_path: Path) -> None:
    assert main(["cards", "add", "--model", str(small_card), "--name", "x", "--data", "d", "--suite", "s"]) == 2
    assert main(["cards", "add", "--model", str(small_card), "--name", "validation", "--suite", "s"]) == 2
    assert main(["cards", "add", "--name", "x", "--suite", "s"]) == 2  # no model
