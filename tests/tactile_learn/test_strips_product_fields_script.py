"""scripts/strips_product_fields.py: product fields are the intersection rule's own case, and the folder it
writes is an ordinary, reproducible dataset of the strips16 sensor that training reads beside others."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from synth.dataset import Dataset
from synth.scene import load_scene
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.tasks import get_task
from tactile_learn.training_sets import TrainingSet
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_product_fields as products


def test_profiles_are_non_negative_with_a_positive_sum() -> None:
    p = products.profiles(300, 64, 0.625, np.random.default_rng(0))
    assert p.shape == (300, 64) and (p >= 0).all() and (p.sum(axis=1) > 0).all()
    assert (p == 1.0).all(axis=1).any()  # some profiles are flat across the array


def test_the_rule_recovers_product_fields_and_their_truth_is_the_sensor_models() -> None:
    scene = products.product_scene()
    frames = products.draw(scene, 64, np.random.default_rng(1))
    assert frames["readings"].shape == (64, 32) and frames["pressure"].shape == (64, 16, 16)
    assert np.isfinite(frames["readings"]).all() and (frames["pressure"] >= 0).all()
    rule = resolve_method("strips", "intersection", load_scene("strips16")).predict(frames["readings"])
    r = pearson_per_frame(rule, frames["pressure"])
    assert np.nanmedian(r) > 0.95  # the outer product is the field, up to the cover's blur and noise


def test_the_folder_is_a_reproducible_dataset_of_the_strips16_sensor(tmp_path: Path) -> None:
    products.write(70, 5, tmp_path / "a")
    products.write(70, 5, tmp_path / "b")
    a, b = Dataset(tmp_path / "a"), Dataset(tmp_path / "b")
    assert len(a) == 70 and a.scene.name == "strips16_product_fields"
    np.testing.assert_array_equal(a.array("readings"), b.array("readings"))
    np.testing.assert_array_equal(a.array("pressure"), b.array("pressure"))
    assert get_task("strips").same_sensor(load_scene("strips16_wide"), a.scene)
    mixed = TrainingSet([str(tmp_path / "a"), str(tmp_path / "b")], get_task("strips").same_sensor)
    assert len(mixed) == 140 and set(mixed.keys) == {"readings", "pressure"}
