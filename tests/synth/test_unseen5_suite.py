"""The strips16_unseen5 suite (unseen shapes, round 5): it parses, every family generates frames
within the sensor's range, and every family lies outside every strip scene in synth/scenes/ (the
mixed scenes, the object scenes, the large rings, the five-part objects, the twins), the OOD suite
and rounds 1-4, checked as round 4 checks itself (tests/synth/test_unseen4_suite.py): from the TOML
files (counts, shapes, arrangements) and in drawn frames (a predicate per family accepts its own
frames and no frame of any reference).

The next candidate (a mixture of experts) also trains on new scenes this suite was written without
seeing; what they draw cannot be checked here.
"""

from __future__ import annotations

import dataclasses
from functools import cache

import numpy as np
import pytest

from synth.scene import Scene, load_scene
from synth.sensors.strips.config import ContactObject, StripStimuli
from synth.suite import Suite, load_suite
from tests.paths import REPO_ROOT
from tests.synth.test_objects_scenes import draw
from tests.synth.test_unseen3_suite import EARLIER_SUITES, assert_no_frame_drawn, assert_outside, novelty
from tests.synth.test_unseen3_suite import assert_own_frames_accepted as assert_own_frames_accepted_by
from tests.synth.test_unseen4_suite import looks_like
from tests.synth.test_unseen4_suite import references as round4_references
from tests.synth.test_unseen_suite import assert_frames_within_range

SUITE = "strips16_unseen5"
ROUND_4 = "strips16_unseen4"
#: every scene of the 16 x 16 strips that a model may have trained on
STRIP_SCENES = tuple(sorted(p.stem for p in (REPO_ROOT / "synth" / "scenes").glob("strips16*.toml")))


@cache
def references() -> dict[str, Scene]:
    """Round 4's references and families, and the strip scenes round 4 did not know (the large rings,
    the five-part objects, the twins)."""
    refs = {**round4_references(), **{f"{ROUND_4}/{f.name}": f.scene for f in load_suite(ROUND_4).families}}
    refs.update({name: load_scene(name) for name in STRIP_SCENES if name not in refs})
    return refs


@pytest.fixture(scope="module")
def suite() -> Suite:
    return load_suite(SUITE)


def test_suite_parses_with_its_families_described(suite: Suite) -> None:
    assert suite.base.name == "strips16" and len(suite.families) == 12
    assert not [f.name for f in suite.families if len(f.description) <= 40]
    earlier = set().union(*(load_suite(s).names for s in (*EARLIER_SUITES, "strips16_unseen3", ROUND_4)))
    assert not set(suite.names) & earlier
    # every strip scene is a reference, and so is every family of the five earlier suites
    assert set(STRIP_SCENES) <= set(references()) and len(STRIP_SCENES) >= 20
    families = sum(len(load_suite(s).families) for s in (*EARLIER_SUITES, "strips16_unseen3", ROUND_4))
    assert families == 11 + 13 + 12 + 12 + 12
    assert len(references()) == len(STRIP_SCENES) + families


def test_every_family_lies_outside_every_strip_scene_the_ood_suite_and_rounds_1_to_4(suite: Suite) -> None:
    assert_outside(suite, references())


def test_the_novelty_check_can_fail(suite: Suite) -> None:
    """The same object on both sides is no reason; the ringed finger is new to the wide scene by its
    pad's width (the wide scene's tilted blocks stop at 14 mm) and by its arrangement, and a narrower
    pad and the band placed independently are two contacts it draws; the keypad is new to the wide scene by its
    count alone, and the jar lid by its ring's radius, which a ring of the large-rings scene's ranges
    loses."""
    wide = load_scene("strips16_wide").sensor.stimuli
    finger = suite.family("finger_with_ring").scene.sensor.stimuli
    assert novelty(finger, finger) == []
    assert novelty(finger, wide) == ["block outside its ranges", "parts of one object"]
    narrower = dataclasses.replace(finger.kinds[0], width_mm=(12.0, 13.5))
    assert novelty(dataclasses.replace(finger, kinds=(narrower, finger.kinds[1]), object=None), wide) == []
    keypad = suite.family("remote_keypad").scene.sensor.stimuli
    assert novelty(dataclasses.replace(keypad, object=None), wide) == ["[12] contacts (reference: [1, 2, 3, 4, 6])"]
    rings = load_scene("strips16_large_rings").sensor.stimuli
    lid = suite.family("jar_lid_rim").scene.sensor.stimuli
    assert novelty(lid, rings) == ["ring outside its ranges"]
    smaller = dataclasses.replace(lid.kinds[0], radius_mm=(15.0, 18.0), hole_fraction=(0.93, 0.95))
    assert novelty(dataclasses.replace(lid, kinds=(smaller,)), rings) == []


def test_every_family_generates_frames_within_the_sensors_range(suite: Suite) -> None:
    # well below the ADC's full scale (the strongest of 200 noise-free frames a family: 0.36 of it)
    assert_frames_within_range(suite, full_scale_share=0.6)


def test_each_familys_predicate_accepts_its_own_frames(suite: Suite) -> None:
    assert_own_frames_accepted_by(suite, looks_like)


def test_an_arrangement_predicate_can_fail(suite: Suite) -> None:
    """The ringed finger's pad and band placed independently on the array: the predicate accepts the
    frames whose band happens to lie 9-14 mm from the pad's centre, and only those."""
    fam = suite.family("finger_with_ring")
    stimuli = fam.scene.sensor.stimuli
    scattered = dataclasses.replace(
        fam.scene, sensor=dataclasses.replace(fam.scene.sensor, stimuli=dataclasses.replace(stimuli, object=None))
    )
    contacts, names = draw(scattered, 2000, seed=4)
    hits = looks_like(stimuli, contacts, names)
    gap = np.hypot(contacts["x_mm"][:, 0] - contacts["x_mm"][:, 1], contacts["y_mm"][:, 0] - contacts["y_mm"][:, 1])
    assert 0.02 < hits.mean() < 0.5
    assert ((gap[hits] >= 9.0 * 0.98) & (gap[hits] <= 14.0 * 1.02)).all()


def test_a_grid_predicate_tells_the_keypad_from_a_square_grid(suite: Suite) -> None:
    """The keypad's keys on a square 3 x 4 grid (rows as far apart as columns) are another object:
    the keypad's predicate rejects every frame of it, and accepts them again once the grid is the
    keypad's."""
    fam = suite.family("remote_keypad")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    square = ContactObject(
        offsets_mm=tuple((x, round(y / 0.74, 6)) for x, y in stimuli.object.offsets_mm),
        rotation_deg=stimuli.object.rotation_deg,
        scale=(8.5, 9.0),
    )
    squared = dataclasses.replace(
        fam.scene, sensor=dataclasses.replace(fam.scene.sensor, stimuli=dataclasses.replace(stimuli, object=square))
    )
    contacts, names = draw(squared, 500, seed=4)
    assert not looks_like(stimuli, contacts, names).any()
    assert looks_like(squared.sensor.stimuli, contacts, names).all()


@pytest.mark.parametrize("reference", sorted(references()))
def test_no_reference_draws_a_frame_of_any_family(suite: Suite, reference: str) -> None:
    assert_no_frame_drawn(suite, reference, references()[reference], looks_like)


def test_every_family_but_the_single_contacts_is_an_object(suite: Suite) -> None:
    """The families of one contact are new by their shape alone; every other family places its
    contacts as the parts of one object (the arrangement the predicates check)."""
    assert_objects_but_the_single_contacts(suite, {"jar_lid_rim", "tape_roll_flat", "book_corner", "tumbler_base"})


def assert_objects_but_the_single_contacts(suite: Suite, single: set[str]) -> None:
    """``single`` are exactly the suite's families of one contact, and every other family is an object."""
    assert {f.name for f in suite.families if f.scene.sensor.stimuli.count == (1, 1)} == single
    for fam in suite.families:
        stimuli: StripStimuli = fam.scene.sensor.stimuli
        assert (stimuli.object is None) == (fam.name in single), fam.name
