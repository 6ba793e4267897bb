"""The strips16_unseen8 suite (unseen shapes, round 8): it parses, every family generates frames
within the sensor's range, and every family lies outside every strip scene in synth/scenes/, the OOD
suite and rounds 1-7, checked as rounds 4-7 check themselves: from the TOML files (counts, shapes,
arrangements) and in drawn frames (a predicate per family accepts its own frames and no frame of any
reference).

Written blind, after the candidate of docs/strips.md's 'Round 8' section was declared and before any
model was evaluated on the suite: what this round can say is that no *object* here is one a scene or
an earlier round draws.
"""

from __future__ import annotations

import dataclasses
from functools import cache

import pytest

from synth.scene import Scene, load_scene
from synth.suite import Suite, load_suite
from tests.synth.test_unseen3_suite import assert_no_frame_drawn, assert_outside, novelty
from tests.synth.test_unseen3_suite import assert_own_frames_accepted as assert_own_frames_accepted_by
from tests.synth.test_unseen4_suite import looks_like
from tests.synth.test_unseen5_suite import assert_objects_but_the_single_contacts
from tests.synth.test_unseen7_suite import (
    assert_round_parses,
    assert_told_apart,
    references_with,
    rounds_through,
    with_stimuli,
)
from tests.synth.test_unseen7_suite import references as round7_references
from tests.synth.test_unseen_suite import assert_frames_within_range

SUITE = "strips16_unseen8"
ROUND_7 = "strips16_unseen7"
EARLIER_ROUNDS = rounds_through(7)


@cache
def references() -> dict[str, Scene]:
    """Round 7's references (every strip scene, the OOD suite, rounds 1-6), round 7's families, and any
    strip scene added since."""
    return references_with(round7_references(), ROUND_7)


@pytest.fixture(scope="module")
def suite() -> Suite:
    return load_suite(SUITE)


def test_suite_parses_with_its_families_described(suite: Suite) -> None:
    assert_round_parses(suite, EARLIER_ROUNDS, references(), 11 + 13 + 12 + 12 + 12 + 12 + 12 + 12)


def test_every_family_lies_outside_every_strip_scene_the_ood_suite_and_rounds_1_to_7(suite: Suite) -> None:
    assert_outside(suite, references())


def test_the_novelty_check_can_fail(suite: Suite) -> None:
    """The same object on both sides is no reason; the plug is new to the wide scene by its arrangement
    alone (its pins placed independently are pads the wide scene draws); the domino is new to the wide
    scene by its pad's size, and a tilted block of the wide scene's sizes is not; the eraser is new to
    it by its tilt, which an untilted eraser loses; the tweezers by their tips' width and their pairing."""
    wide = load_scene("strips16_wide").sensor.stimuli
    plug = suite.family("uk_plug_pins").scene.sensor.stimuli
    assert novelty(plug, plug) == []
    assert novelty(plug, wide) == ["parts of one object"]
    assert novelty(dataclasses.replace(plug, object=None), wide) == []
    domino = suite.family("domino_on_its_back").scene.sensor.stimuli
    assert novelty(domino, wide) == ["block outside its ranges"]
    tile = dataclasses.replace(domino.kinds[0], width_mm=(10.0, 12.0), length_mm=(20.0, 25.0))
    assert novelty(dataclasses.replace(domino, kinds=(tile,)), wide) == []
    eraser = suite.family("pencil_eraser_slanted").scene.sensor.stimuli
    assert novelty(eraser, wide) == ["punch outside its ranges"]
    upright = dataclasses.replace(eraser.kinds[0], tilt=(0.0, 0.0))
    assert novelty(dataclasses.replace(eraser, kinds=(upright,)), wide) == []
    tips = suite.family("tweezer_tips").scene.sensor.stimuli
    assert novelty(tips, wide) == ["block outside its ranges", "parts of one object"]


def test_every_family_generates_frames_within_the_sensors_range(suite: Suite) -> None:
    # well below the ADC's full scale (the strongest of the six frames a family: the plug, 0.41 of it)
    assert_frames_within_range(suite, full_scale_share=0.5)


def test_each_familys_predicate_accepts_its_own_frames(suite: Suite) -> None:
    assert_own_frames_accepted_by(suite, looks_like)


def test_a_triangle_predicate_tells_the_uk_plug_from_an_equilateral_one(suite: Suite) -> None:
    """The same three pins on an equilateral triangle of the plug's 22.2 mm base (round 3's tripod's
    shape) are another object: the plug's predicate rejects every frame of it."""
    fam = suite.family("uk_plug_pins")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    equilateral = dataclasses.replace(stimuli.object, offsets_mm=((-11.1, -6.4086), (11.1, -6.4086), (0.0, 12.8172)))
    other = with_stimuli(fam, object=equilateral)
    assert_told_apart(stimuli, other)


def test_the_digits_predicate_sees_the_gap_between_groups(suite: Suite) -> None:
    """The same eight digits evenly spaced (no space between the groups of four) are another line: the
    card's predicate rejects every frame of it."""
    fam = suite.family("credit_card_digits")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    even = dataclasses.replace(stimuli.object, offsets_mm=tuple((x - 3.5, 0.0) for x in range(8)))
    other = with_stimuli(fam, object=even)
    assert_told_apart(stimuli, other)


def test_the_paw_predicate_counts_its_claws(suite: Suite) -> None:
    """A paw whose claws are four more toe pads (every part a sphere) passes the sizes and the
    arrangement but not the kinds' count: the dog's paw predicate rejects every frame of it."""
    fam = suite.family("dog_paw_with_claws")
    stimuli = fam.scene.sensor.stimuli
    toe = stimuli.kinds[1]
    assert toe.kind == "sphere" and [k.kind for k in stimuli.kinds[5:]] == ["punch"] * 4
    clawless = with_stimuli(fam, kinds=(*stimuli.kinds[:5], toe, toe, toe, toe))
    assert_told_apart(stimuli, clawless)


@pytest.mark.parametrize("reference", sorted(references()))
def test_no_reference_draws_a_frame_of_any_family(suite: Suite, reference: str) -> None:
    assert_no_frame_drawn(suite, reference, references()[reference], looks_like)


def test_every_family_but_the_single_contacts_is_an_object(suite: Suite) -> None:
    """The families of one contact are new by their shape alone; every other family places its
    contacts as the parts of one object (the arrangement the predicates check)."""
    assert_objects_but_the_single_contacts(
        suite, {"domino_on_its_back", "pencil_eraser_slanted", "sponge_under_a_hand", "can_ring_pull"}
    )
