"""tactile_learn.methods: what a ``--method`` value resolves to (classical name, shipped model, .onnx path)."""

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
from tactile_learn.methods import (
    available_methods,
    model_dirs,
    model_scene,
    resolve_method,
    shipped_cards,
    shipped_models,
)
from tactile_learn.tasks import get_task

MODELS = Path(__file__).resolve().parents[2] / "models"


@pytest.fixture()
def own_models(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A user's model folder (``$TACTILE_LEARN_MODELS``) holding a copy of the strips5 model."""
    folder = tmp_path / "my-models"
    folder.mkdir()
    for suffix in (".onnx", ".json"):
        shutil.copy(MODELS / f"strips5{suffix}", folder / f"mine{suffix}")
    monkeypatch.setenv("TACTILE_LEARN_MODELS", str(folder))
    return folder


def test_classical_names_resolve_to_their_estimators() -> None:
    scene = load_scene("strips16")
    for name, factory in get_task("strips").classical_methods().items():
        estimator = resolve_method("strips", name, scene)
        assert type(estimator) is factory.estimator_class  # type: ignore[attr-defined]  # prepared(cls)
        assert estimator.name == name


def test_an_unknown_method_names_what_exists() -> None:
    with pytest.raises(ConfigError) as info:
        resolve_method("strips", "magic", load_scene("strips16"))
    message = str(info.value)
    assert "'magic'" in message and "intersection" in message and "strips16" in message


def test_a_missing_model_file_and_a_model_of_another_task_are_refused() -> None:
    scene = load_scene("strips16")
    with pytest.raises(ModelError, match="not found"):
        resolve_method("strips", "nowhere/model.onnx", scene)
    with pytest.raises(ModelError, match="for task 'thermal'"):
        resolve_method("strips", str(MODELS / "thermal.onnx"), scene)


def test_shipped_models_are_listed_by_task() -> None:
    strips = shipped_models("strips")
    assert {"strips16", "strips5"} <= set(strips)
    assert "thermal" not in strips and "thermal" in shipped_models("thermal")
    assert all(path.suffix == ".onnx" and path.is_file() for path in strips.values())


def test_a_users_model_folder_comes_first_and_its_models_resolve(own_models: Path) -> None:
    assert model_dirs()[0] == own_models
    assert "mine" in available_methods("strips")
    scene = load_scene("strips5")
    estimator = resolve_method("strips", "mine", scene)
    readings = np.full((3, *get_task("strips").input_shape(scene)), 0.4, dtype=np.float32)
    reference = resolve_method("strips", str(MODELS / "strips5.onnx"), scene)
    np.testing.assert_array_equal(estimator.predict(readings), reference.predict(readings))


def test_a_corrupt_card_hides_the_model_from_the_list_and_fails_clearly_when_named(own_models: Path) -> None:
    (own_models / "mine.json").write_text("{ not json")
    assert "mine" not in shipped_models("strips")
    with pytest.raises(ModelError):
        resolve_method("strips", str(own_models / "mine.onnx"), load_scene("strips5"))


def test_a_tampered_model_file_is_refused(own_models: Path) -> None:
    blob = bytearray((own_models / "mine.onnx").read_bytes())
    blob[len(blob) // 2] ^= 0xFF
    (own_models / "mine.onnx").write_bytes(bytes(blob))
    with pytest.raises(ModelError):
        resolve_method("strips", "mine", load_scene("strips5"))


def test_model_scene_is_the_cards_scene_and_none_for_classical_methods() -> None:
    assert model_scene("strips", "intersection") is None
    scene = model_scene("strips", "strips5")
    assert scene is not None and scene.task == "strips"
    assert scene.digest == load_scene("strips5").digest
    assert model_scene("strips", "no-such-model") is None


def test_a_model_for_another_sensor_of_the_same_task_is_refused_with_the_shapes() -> None:
    with pytest.raises(ModelError):
        resolve_method("strips", "strips5", load_scene("strips16"))


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
    assert all(card["task"] == "strips" and path.stem == name for name, (path, card) in cards.items())
    assert "fsr" not in cards


def test_a_corrupt_model_fails_when_it_is_resolved_but_its_scene_is_still_read(tmp_path: Path) -> None:
    model = tmp_path / "m.onnx"
    model.write_bytes((MODELS / "strips5.onnx").read_bytes()[:-10] + b"0123456789")
    shutil.copy(MODELS / "strips5.json", tmp_path / "m.json")
    with pytest.raises(ModelError, match="checksum"):
        resolve_method("strips", str(model), load_scene("strips5"))
    assert model_scene("strips", str(model)) is not None  # the scene is read without the checksum


def test_torch_weights_resolve_through_the_one_loader_and_agree_with_their_onnx_export() -> None:
    pytest.importorskip("torch", reason="torch weights need torch")
    scene = load_scene("strips5")
    weights = resolve_method("strips", str(MODELS / "strips5.pt"), scene)
    assert weights.backend == "torch" and weights.task_name == "strips"  # type: ignore[attr-defined]
    readings = simulate_shard(scene, 8, 0, 16)["readings"]
    onnx = resolve_method("strips", "strips5", scene)
    np.testing.assert_allclose(weights.predict(readings), onnx.predict(readings), rtol=1e-4, atol=1e-4)
    scene_of_weights = model_scene("strips", str(MODELS / "strips5.pt"))
    assert scene_of_weights is not None and scene_of_weights.digest == scene.digest
    with pytest.raises(ModelError, match="weights are for task 'strips'"):
        resolve_method("fsr", str(MODELS / "strips5.pt"), load_scene("fsr6"))
