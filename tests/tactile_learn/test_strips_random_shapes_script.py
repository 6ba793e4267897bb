"""scripts/strips_random_shapes.py: shapes from no named object - specks to areas larger than the
array, rims, streaks at any angle - written as an ordinary, reproducible dataset of the strips16 sensor."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from synth.dataset import Dataset
from synth.scene import load_scene
from tactile_learn.tasks import get_task
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_random_shapes as shapes


def test_shapes_are_non_negative_and_span_specks_to_most_of_the_array() -> None:
    rng = np.random.default_rng(0)
    drawn = np.stack([shapes.shape(64, 0.625, rng) for _ in range(300)])
    assert (drawn >= 0).all() and (drawn.sum(axis=(1, 2)) > 0).all()
    covered = (drawn > 0).mean(axis=(1, 2))
    assert covered.min() < 0.03 and covered.max() > 0.6  # the log-uniform share of the array, both ends
    flat = [(s[s > 0].max() == s[s > 0].min()) for s in drawn]
    assert 0.2 < np.mean(flat) < 0.8  # rigid (flat) and soft shapes both drawn


def test_some_fields_are_long_streaks() -> None:
    """The aspect reaches streaks: a field whose gradient is almost all across one direction."""
    rng = np.random.default_rng(3)
    # draw until a strongly elongated field (the aspect is random); its gradient is across the streak
    for _ in range(200):
        g = shapes.smooth_noise(64, 32, 0.625, rng)
        gr, gc = np.gradient(g)
        cov = np.cov(np.stack([gr.ravel(), gc.ravel()]))
        ratio = np.linalg.eigvalsh(cov)
        if ratio[1] > 50 * ratio[0]:
            return
    raise AssertionError("no elongated field in 200 draws")


def test_the_folder_is_a_reproducible_dataset_of_the_strips16_sensor(tmp_path: Path) -> None:
    shapes.write(40, 7, tmp_path / "a")
    shapes.write(40, 7, tmp_path / "b")
    a, b = Dataset(tmp_path / "a"), Dataset(tmp_path / "b")
    assert len(a) == 40 and a.scene.name == "strips16_random_shapes"
    np.testing.assert_array_equal(a.array("readings"), b.array("readings"))
    np.testing.assert_array_equal(a.array("pressure"), b.array("pressure"))
    assert np.isfinite(a.array("readings")).all() and (a.array("pressure") >= 0).all()
    assert get_task("strips").same_sensor(load_scene("strips16_wide"), a.scene)
