"""The training scenes for what round 3 of the unseen shapes found missing (synth/scenes/strips16_large_rings.toml
and strips16_five_*.toml): large thin rings wholly or mostly on the array, and five contacts as the parts of
one rigid object. They share strips16_wide's sensor, generate below the readout's full scale, and hold
out in drawn frames what the earlier evaluations press: round 1's thin rims and five fingertips, round
2's objects, the ood suite's washers and terminals, and round 1's shape intervals."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from synth.scene import Scene, load_scene
from synth.suite import load_suite
from tests.paths import REPO_ROOT
from tests.synth.test_objects_scenes import (
    ROUND2,
    Contacts,
    _distance,
    assert_pressed_below_full_scale,
    assert_wide_sensor,
    draw,
    within,
)
from tests.synth.test_wide_scene import UNSEEN, held_out

FIVE = sorted(p.stem for p in (Path(REPO_ROOT) / "synth" / "scenes").glob("strips16_five_*.toml"))
RINGS = "strips16_large_rings"
NAMES = [RINGS, *FIVE]
#: round 1's thin rims (hole fraction), held out of the ring scene
THIN_RIM = (0.86, 0.93)


def five_fingertips(c: Contacts, kinds: np.ndarray) -> np.ndarray:
    """Round 1's five fingertips: frames of five contacts, every one a sphere of 6-10 mm radius."""
    tips = (kinds == "sphere") & within(c["radius_mm"], 6.0, 10.0)
    return np.asarray((c["count"] == 5) & (tips.sum(axis=1) == 5))


@pytest.fixture(scope="module")
def scenes() -> dict[str, Scene]:
    return {name: load_scene(name) for name in NAMES}


@pytest.fixture(scope="module")
def drawn(scenes: dict[str, Scene]) -> dict[str, tuple[Contacts, np.ndarray]]:
    return {name: draw(scene, 6000, seed=7) for name, scene in scenes.items()}


def test_the_scenes_exist_and_share_the_wide_scenes_sensor(scenes: dict[str, Scene]) -> None:
    assert len(FIVE) >= 3
    assert_wide_sensor(scenes)


@pytest.mark.parametrize("name", NAMES)
def test_generates_pressed_frames_below_full_scale(scenes: dict[str, Scene], name: str) -> None:
    assert_pressed_below_full_scale(scenes[name], seed=13, size=100)


def test_rings_are_large_thin_and_mostly_on_the_array(scenes: dict[str, Scene], drawn: dict) -> None:
    contacts, kinds = drawn[RINGS]
    assert (contacts["count"] == 1).all() and (kinds[:, 0] == "ring").all()
    radius, hole = contacts["radius_mm"][:, 0], contacts["hole_fraction"][:, 0]
    assert within(radius, 10.0, 19.0).all() and radius.max() > 18.0
    assert not within(hole, *THIN_RIM).any()
    # both sides of round 1's thin rims are drawn: cups' rings thicker and thinner than its rims
    assert within(hole, 0.75, THIN_RIM[0]).mean() > 0.5 and (hole > THIN_RIM[1]).mean() > 0.1
    # the ring's centre keeps every ring mostly on the array: at most 5 mm of the largest off an edge
    side = scenes[RINGS].sensor.geometry.n_rows * scenes[RINGS].sensor.geometry.pitch_mm
    for axis in ("x_mm", "y_mm"):
        reach = np.maximum(-(contacts[axis][:, 0] - radius), contacts[axis][:, 0] + radius - side)
        assert reach.max() <= 5.0 + 1e-6
    assert ((radius <= 12.0) & (reach <= 0.0)).any()  # small rings wholly on it


def test_five_part_objects_keep_their_arrangement(drawn: dict) -> None:
    """Rigid objects of five: every frame has five parts, and the ratio of two part distances is the
    arrangement's, whatever the frame's scale and turn."""
    for name in FIVE:
        contacts, kinds = drawn[name]
        assert (contacts["count"] == 5).all() and (kinds != "").all(), name
        ratio = _distance(contacts, 0, 1) / _distance(contacts, 1, 2)
        assert np.ptp(ratio) < 1e-6, name


def test_five_fingertips_predicate_recognises_round_1s_family() -> None:
    """The check below can fail: it flags every frame of round 1's five fingertips."""
    family = {f.name: f for f in load_suite("strips16_unseen").families}["five_fingertips"]
    contacts, kinds = draw(family.scene, 400, seed=3)
    assert five_fingertips(contacts, kinds).all()


@pytest.mark.parametrize("name", NAMES)
def test_earlier_rounds_stay_held_out(scenes: dict[str, Scene], drawn: dict, name: str) -> None:
    contacts, kinds = drawn[name]
    present = kinds != ""
    assert not five_fingertips(contacts, kinds).any(), name
    for family, predicate in ROUND2.items():
        assert not predicate(contacts, kinds).any(), (name, family)
    for family, (kind, parameter, lo, hi) in UNSEEN.items():
        value = contacts[parameter][kinds == kind]
        inside = within(value, lo, hi) if hi > lo else np.abs(value - lo) < 0.02
        assert not inside.any(), (name, family)
    assert (contacts["force_n"][present] >= 0.2).all()
    assert set(kinds[present].tolist()) <= {"sphere", "punch", "ring"}
    stimuli = scenes[name].sensor.stimuli
    for ood in load_suite("strips16_ood").families:
        if ood.name in ("washer", "two_washers", "ring_terminal", "block_30deg", "block_60deg", "tilted_block"):
            assert held_out(stimuli, ood.scene.sensor.stimuli), (name, ood.name)


def test_five_part_scenes_differ_in_arrangement(drawn: dict) -> None:
    """Several arrangements, not one: the sorted pairwise distances over the object's span differ."""
    shapes = []
    for name in FIVE:
        contacts, _ = drawn[name]
        d = np.stack([_distance(contacts, i, j) for i, j in itertools.combinations(range(5), 2)], axis=1)
        shapes.append(np.sort(d[0] / d[0].max()))
    for a, b in itertools.combinations(shapes, 2):
        assert np.abs(a - b).max() > 0.05
