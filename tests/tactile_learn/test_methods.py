"""The method loader: a ``--method`` value to an estimator, each model card read once."""

from __future__ import annotations

import shutil
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.errors import ConfigError, ModelError
from synth.scene import load_scene
from tactile_learn.methods import model_scene, resolve_method, shipped_cards

MODELS = Path(__file__).resolve().parents[2] / "models"


@pytest.fixture()
def card_reads(monkeypatch: pytest.MonkeyPatch) -> Counter[str]:
    """Every read of a ``.json`` file, by file name, however the code reads it."""
    reads: Counter[str] = Counter()
    original = Path.read_text

    def counting(self: Path, *args: Any, **kwargs: Any) -> str:
        if self.suffix == ".json":
            reads[self.name] += 1
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Path, "read_text", counting)
    return reads


@pytest.mark.parametrize("spec", ["strips5", str(MODELS / "strips5.onnx")])
def test_a_model_card_is_read_once_from_resolving_to_predicting(spec: str, card_reads: Counter[str]) -> None:
    scene = load_scene("strips5")
    model = resolve_method("strips", spec, scene)
    readings = simulate_shard(scene, 5, 0, 4)["readings"]
    maps = model.predict(readings)
    assert maps.shape == (4, 5, 5) and np.isfinite(maps).all()
    assert card_reads["strips5.json"] == 1


def test_shipped_cards_offers_each_model_of_the_task_with_its_card() -> None:
    cards = shipped_cards("strips")
    assert {"strips5", "strips16"} <= set(cards)
    assert all(card["task"] == "strips" for _, card in cards.values())
    assert "fsr" not in cards


def test_a_corrupt_model_fails_when_it_is_resolved(tmp_path: Path) -> None:
    model = tmp_path / "m.onnx"
    model.write_bytes((MODELS / "strips5.onnx").read_bytes()[:-10] + b"0123456789")
    shutil.copy(MODELS / "strips5.json", tmp_path / "m.json")
    with pytest.raises(ModelError, match="checksum"):
        resolve_method("strips", str(model), load_scene("strips5"))
    assert model_scene("strips", str(model)) is not None  # the scene is read without the checksum


def test_a_model_of_another_task_or_an_unknown_name_is_refused() -> None:
    with pytest.raises(ModelError, match="for task 'fsr'"):
        resolve_method("strips", str(MODELS / "fsr.onnx"), load_scene("strips5"))
    with pytest.raises(ConfigError, match="not a method of task"):
        resolve_method("strips", "no_such_model", load_scene("strips5"))
