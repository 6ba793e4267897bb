"""scripts/strips_arrangements.py: many parts of one primitive on a random lattice - grids, rows, circles,
radiating lines, clusters - written as an ordinary, reproducible dataset of the strips16 sensor."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
from scipy import ndimage

from synth.dataset import Dataset
from synth.scene import load_scene
from tactile_learn.tasks import get_task
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_arrangements as arrangements

H_MM = 0.625


def lattice() -> tuple[np.ndarray, np.ndarray]:
    x = (np.arange(64) + 0.5) * H_MM - 20.0
    return np.meshgrid(x, x, indexing="ij")


def test_shapes_are_non_negative_and_most_hold_several_separate_parts() -> None:
    rng = np.random.default_rng(0)
    drawn = [arrangements.shape(64, H_MM, rng) for _ in range(300)]
    assert all((p >= 0).all() and p.sum() > 0 for p in drawn)
    parts = np.array([ndimage.label(p > 0)[1] for p in drawn])
    assert np.mean(parts >= 3) > 0.4 and parts.max() >= 12  # many parts, not one blob
    covered = np.array([(p > 0).mean() for p in drawn])
    assert covered.min() < 0.01 and covered.max() > 0.3


def test_every_layout_places_its_parts_as_named() -> None:
    rng = np.random.default_rng(1)
    for _ in range(20):
        xy, _ = arrangements.sites("circles", rng)
        radii = np.unique(np.round(np.hypot(xy[:, 0], xy[:, 1]), 6))
        assert 1 <= len(radii) <= 2 and len(xy) >= 3  # one or two circles about the origin
        xy, _ = arrangements.sites("row", rng)
        steps = np.hypot(*np.diff(xy, axis=0).T)
        assert np.allclose(steps, steps[0], rtol=0.02)  # evenly spaced along a line or an arc
        xy, _ = arrangements.sites("grid", rng)
        assert len(xy) >= 2
        xy, phi = arrangements.sites("radial", rng)
        assert np.allclose(np.hypot(xy[:, 0], xy[:, 1]), 1.0)  # unit directions (scaled by the line)
        assert np.allclose(xy, np.stack([np.cos(phi), np.sin(phi)], axis=1))


def test_parts_are_centred_where_placed_and_thin_ones_stay_on_the_lattice() -> None:
    xx, yy = lattice()
    for kind, size in (("dome", (2.0, 0.0)), ("pad", (6.0, 9.0)), ("line", (12.0, 1.0)), ("ring", (5.0, 1.0))):
        p = arrangements.raster_part(kind, size, 3.0, -4.0, 0.6, xx, yy, H_MM)
        cx, cy = (p * xx).sum() / p.sum(), (p * yy).sum() / p.sum()
        assert math.isclose(cx, 3.0, abs_tol=0.35) and math.isclose(cy, -4.0, abs_tol=0.35), kind
    thin = arrangements.raster_part("line", (10.0, 0.05), 0.0, 0.0, 0.0, xx, yy, H_MM)  # thinner than a cell
    assert thin.sum() > 0
    ring = arrangements.raster_part("ring", (5.0, 1.0), 0.0, 0.0, 0.0, xx, yy, H_MM)
    assert ring[32, 32] == 0.0 and ring.max() > 0.5  # a hole in the middle


def test_the_folder_is_a_reproducible_dataset_of_the_strips16_sensor(tmp_path: Path) -> None:
    arrangements.write(40, 7, tmp_path / "a")
    arrangements.write(40, 7, tmp_path / "b")
    a, b = Dataset(tmp_path / "a"), Dataset(tmp_path / "b")
    assert len(a) == 40 and a.scene.name == "strips16_arrangements"
    np.testing.assert_array_equal(a.array("readings"), b.array("readings"))
    np.testing.assert_array_equal(a.array("pressure"), b.array("pressure"))
    assert np.isfinite(a.array("readings")).all() and (a.array("pressure") >= 0).all()
    assert get_task("strips").same_sensor(load_scene("strips16_wide"), a.scene)
