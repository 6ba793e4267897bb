"""The strips16_unseen6 suite (unseen shapes, round 6): it parses, every family generates frames
within the sensor's range, and every family lies outside every strip scene in synth/scenes/, the OOD
suite and rounds 1-5, checked as rounds 4 and 5 check themselves: from the TOML files (counts, shapes,
arrangements) and in drawn frames (a predicate per family accepts its own frames and no frame of any
reference).

Written after the random-shape candidates were fixed (scripts/strips_random_shapes.py). They train on
generic fields from no named object (random shapes, product fields), which these checks cannot compare
with: what this round can say is that no *object* here is one a scene or an earlier round draws.
"""

from __future__ import annotations

import dataclasses
from functools import cache

import pytest

from synth.scene import Scene, load_scene
from synth.suite import Suite, load_suite
from tests.synth.test_objects_scenes import draw
from tests.synth.test_unseen3_suite import EARLIER_SUITES, assert_no_frame_drawn, assert_outside, novelty
from tests.synth.test_unseen3_suite import assert_own_frames_accepted as assert_own_frames_accepted_by
from tests.synth.test_unseen4_suite import looks_like
from tests.synth.test_unseen5_suite import STRIP_SCENES, assert_objects_but_the_single_contacts
from tests.synth.test_unseen5_suite import references as round5_references
from tests.synth.test_unseen_suite import assert_frames_within_range

SUITE = "strips16_unseen6"
ROUND_5 = "strips16_unseen5"
EARLIER_ROUNDS = (*EARLIER_SUITES, "strips16_unseen3", "strips16_unseen4", ROUND_5)


@cache
def references() -> dict[str, Scene]:
    """Round 5's references (every strip scene, the OOD suite, rounds 1-4), round 5's families, and any
    strip scene added since."""
    refs = {**round5_references(), **{f"{ROUND_5}/{f.name}": f.scene for f in load_suite(ROUND_5).families}}
    refs.update({name: load_scene(name) for name in STRIP_SCENES if name not in refs})
    return refs


@pytest.fixture(scope="module")
def suite() -> Suite:
    return load_suite(SUITE)


def test_suite_parses_with_its_families_described(suite: Suite) -> None:
    assert suite.base.name == "strips16" and len(suite.families) == 12
    assert not [f.name for f in suite.families if len(f.description) <= 40]
    earlier = set().union(*(load_suite(s).names for s in EARLIER_ROUNDS))
    assert not set(suite.names) & earlier
    assert set(STRIP_SCENES) <= set(references()) and len(STRIP_SCENES) >= 20
    families = sum(len(load_suite(s).families) for s in EARLIER_ROUNDS)
    assert families == 11 + 13 + 12 + 12 + 12 + 12
    assert len(references()) == len(STRIP_SCENES) + families


def test_every_family_lies_outside_every_strip_scene_the_ood_suite_and_rounds_1_to_5(suite: Suite) -> None:
    assert_outside(suite, references())


def test_the_novelty_check_can_fail(suite: Suite) -> None:
    """The same object on both sides is no reason; the phone is new to the wide scene by its plate's
    size alone, and a tilted block of the wide scene's sizes, angles and forces is not; the bubble wrap
    is new to the same ten spheres placed independently by its lattice."""
    wide = load_scene("strips16_wide").sensor.stimuli
    phone = suite.family("phone_lying_flat").scene.sensor.stimuli
    assert novelty(phone, phone) == []
    assert novelty(phone, wide) == ["block outside its ranges"]
    smaller = dataclasses.replace(
        phone.kinds[0], width_mm=(10.0, 12.0), length_mm=(20.0, 25.0), angle_deg=(0.0, 20.0), force_n=(1.0, 8.0)
    )
    assert novelty(dataclasses.replace(phone, kinds=(smaller,)), wide) == []
    bubbles = suite.family("bubble_wrap").scene.sensor.stimuli
    assert novelty(bubbles, dataclasses.replace(bubbles, object=None)) == ["parts of one object"]


def test_every_family_generates_frames_within_the_sensors_range(suite: Suite) -> None:
    # below the ADC's full scale (the strongest of the six frames a family: the bottle, 0.56 of it)
    assert_frames_within_range(suite, full_scale_share=0.6)


def test_each_familys_predicate_accepts_its_own_frames(suite: Suite) -> None:
    assert_own_frames_accepted_by(suite, looks_like)


def test_a_lattice_predicate_tells_bubble_wrap_from_a_square_grid(suite: Suite) -> None:
    """The same ten bubbles on a square grid (two rows of five, the bubble wrap's pitch, allowed 5 mm
    off the array to fit) are another object: the bubble wrap's predicate rejects every frame of it."""
    fam = suite.family("bubble_wrap")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    square = dataclasses.replace(
        stimuli.object, offsets_mm=tuple((float(x), float(y)) for y in (-0.5, 0.5) for x in (-2, -1, 0, 1, 2))
    )
    squared = dataclasses.replace(
        fam.scene,
        sensor=dataclasses.replace(
            fam.scene.sensor, stimuli=dataclasses.replace(stimuli, object=square, margin_mm=-5.0)
        ),
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
    assert_objects_but_the_single_contacts(suite, {"bottle_on_its_side", "phone_lying_flat"})
