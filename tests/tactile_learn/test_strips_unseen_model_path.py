"""scripts/strips_unseen.py takes a model file as well as a shipped name (a candidate exported from a
training run, its card beside it): on the same frames the copy scores exactly as the shipped model,
and a file without its card is refused, naming the card."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest

from synth.errors import ModelError
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_unseen

SHIPPED = "strips16_small"


def _exported_copy(folder: Path) -> Path:
    """The shipped model as a run's export would lie: ``model.onnx`` with ``model.json`` beside it."""
    folder.mkdir()
    onnx_file = folder / "model.onnx"
    shutil.copyfile(REPO_ROOT / "models" / f"{SHIPPED}.onnx", onnx_file)
    shutil.copyfile(REPO_ROOT / "models" / f"{SHIPPED}.json", folder / "model.json")
    return onnx_file


def test_a_model_file_scores_as_the_shipped_model_it_copies(tmp_path: Path) -> None:
    model = str(_exported_copy(tmp_path / "run"))
    out = tmp_path / "unseen3.json"
    argv = [model, SHIPPED, "--suite", "strips16_unseen3", "--n", "6", "--seeds", "3", "--json", str(out)]
    assert strips_unseen.main(argv) == 0
    result = json.loads(out.read_text())
    assert result["suite"] == "strips16_unseen3" and len(result["families"]) == 12
    for name, fam in result["families"].items():
        assert fam["methods"][model] == fam["methods"][SHIPPED], name
        assert fam["models"][model] == fam["models"][SHIPPED], name
    assert result["summary"][model] == result["summary"][SHIPPED]
    assert f"{model}: margin per seed" in out.with_suffix(".md").read_text()


def test_a_model_file_without_its_card_is_refused(tmp_path: Path) -> None:
    model = _exported_copy(tmp_path / "run")
    model.with_suffix(".json").unlink()
    with pytest.raises(ModelError, match="model card not found"):
        strips_unseen.main([str(model), "--suite", "strips16_unseen3", "--n", "2", "--seeds", "3"])
