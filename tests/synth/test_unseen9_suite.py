"""The strips16_unseen9 suite (unseen shapes, round 9): it parses, every family generates frames
within the sensor's range, and every family lies outside every strip scene in synth/scenes/, the OOD
suite and rounds 1-8, checked as rounds 4-8 check themselves: from the TOML files (counts, shapes,
arrangements) and in drawn frames (a predicate per family accepts its own frames and no frame of any
reference).

Written blind, before any model was evaluated on the suite: what this round can say is that no
*object* here is one a scene or an earlier round draws.
"""

from __future__ import annotations

import dataclasses
from functools import cache

import numpy as np
import pytest

from synth.scene import Scene, load_scene
from synth.stimuli import ContactBatch, rasterize, window_cells
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
from tests.synth.test_unseen8_suite import references as round8_references
from tests.synth.test_unseen_suite import assert_frames_within_range

SUITE = "strips16_unseen9"
ROUND_8 = "strips16_unseen8"
EARLIER_ROUNDS = rounds_through(8)


@cache
def references() -> dict[str, Scene]:
    """Round 8's references (every strip scene, the OOD suite, rounds 1-7), round 8's families, and any
    strip scene added since."""
    return references_with(round8_references(), ROUND_8)


@pytest.fixture(scope="module")
def suite() -> Suite:
    return load_suite(SUITE)


def test_suite_parses_with_its_families_described(suite: Suite) -> None:
    assert_round_parses(suite, EARLIER_ROUNDS, references(), 11 + 13 + 12 + 12 + 12 + 12 + 12 + 12 + 12)


def test_every_family_lies_outside_every_strip_scene_the_ood_suite_and_rounds_1_to_8(suite: Suite) -> None:
    assert_outside(suite, references())


def test_the_novelty_check_can_fail(suite: Suite) -> None:
    """The same object on both sides is no reason; the 9-V battery is new to the wide scene by its
    arrangement alone (its stud and socket placed independently are a punch and a ring the wide scene
    draws); the beach ball by its disc having no hole, which a ring with the wide scene's holes loses;
    the teddy bear by its face's correlation length (inside the wide scene's held-out 5-7 mm) and its
    arrangement, and a face of 7.2-8.5 mm is new by the arrangement alone."""
    wide = load_scene("strips16_wide").sensor.stimuli
    battery = suite.family("battery_9v_terminals").scene.sensor.stimuli
    assert novelty(battery, battery) == []
    assert novelty(battery, wide) == ["parts of one object"]
    assert novelty(dataclasses.replace(battery, object=None), wide) == []
    ball = suite.family("beach_ball").scene.sensor.stimuli
    assert novelty(ball, wide) == ["ring outside its ranges"]
    holed = dataclasses.replace(ball.kinds[0], hole_fraction=(0.3, 0.3))
    assert novelty(dataclasses.replace(ball, kinds=(holed,)), wide) == []
    teddy = suite.family("teddy_bear_face").scene.sensor.stimuli
    assert novelty(teddy, wide) == ["blob outside its ranges", "parts of one object"]
    coarser = dataclasses.replace(teddy.kinds[0], width_mm=(7.2, 8.5))
    assert novelty(dataclasses.replace(teddy, kinds=(coarser, *teddy.kinds[1:])), wide) == ["parts of one object"]


def test_every_family_generates_frames_within_the_sensors_range(suite: Suite) -> None:
    # well below the ADC's full scale (the strongest of the six frames a family: the bite, 0.34 of it)
    assert_frames_within_range(suite, full_scale_share=0.5)


def test_each_familys_predicate_accepts_its_own_frames(suite: Suite) -> None:
    assert_own_frames_accepted_by(suite, looks_like)


def test_the_bite_is_a_symmetric_arch(suite: Suite) -> None:
    """The teeth come in mirror pairs (part 2k and 2k+1): the same entry but for a mirrored edge angle,
    at mirrored offsets; the canines' cusps lie 31-34 mm apart, in front of the premolars."""
    stimuli = suite.family("upper_teeth_bite").scene.sensor.stimuli
    assert stimuli.object is not None
    offsets = np.asarray(stimuli.object.offsets_mm)
    assert np.allclose(offsets[0::2] * [-1, 1], offsets[1::2])
    for right, left in zip(stimuli.kinds[0::2], stimuli.kinds[1::2], strict=True):
        assert dataclasses.replace(left, angle_deg=(180 - left.angle_deg[1], 180 - left.angle_deg[0])) == right
    canines = np.ptp(offsets[4:6, 0]) * np.asarray(stimuli.object.scale)
    assert 30.9 <= canines[0] < canines[1] <= 34.3 and offsets[4, 1] < offsets[6:, 1].min()


def test_the_beach_ball_presses_a_flat_topped_disc(suite: Suite) -> None:
    """A ring with no hole is a disc of one pressure, the force over its area (the ball's inflation
    pressure): every cell wholly inside it carries the same load; a punch of the same size peaks at
    its rim instead."""
    scene = suite.family("beach_ball").scene
    spec = scene.sensor.stimuli.kinds[0]
    assert spec.hole_fraction == (0.0, 0.0)
    g = scene.sensor.geometry
    h, e_star = g.pitch_mm / g.samples_per_pitch, scene.sensor.layers.e_star_mpa
    one = {name: np.array([v]) for name, v in {"x_mm": 20.0, "y_mm": 20.0, "force_n": 2.0, "radius_mm": 13.0}.items()}
    zero = np.zeros(1)
    disc = ContactBatch(**one, width_mm=zero, length_mm=zero, angle_deg=zero, hole_fraction=zero)
    size = int(window_cells("ring", disc, h, e_star)[0])
    values = rasterize("ring", disc, h, size, e_star).values[0]
    centres = (np.arange(size) + 0.5 + np.floor(20.0 / h) - size // 2) * h - 20.0
    inside = np.hypot(centres[:, None], centres[None, :]) < 13.0 - h
    assert np.ptp(values[inside]) < 1e-9 * values.max()
    assert values[inside].mean() == pytest.approx(2.0 * 1000 / (np.pi * 13.0**2), rel=0.03)
    punch = rasterize("punch", disc, h, size, e_star).values[0]
    assert punch[inside].max() > 2 * punch[size // 2, size // 2]


def test_an_arch_predicate_tells_the_bite_from_a_round_one(suite: Suite) -> None:
    """The same ten teeth evenly spread on a half circle as wide as the canines are another arch: the
    bite's predicate rejects every frame of it."""
    fam = suite.family("upper_teeth_bite")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    angles = np.deg2rad(np.linspace(0.0, 180.0, 10))
    half_circle = tuple((round(16.3 * float(np.cos(a)), 4), round(16.3 * float(np.sin(a)), 4)) for a in angles)
    round_arch = dataclasses.replace(stimuli.object, offsets_mm=half_circle)
    assert_told_apart(stimuli, with_stimuli(fam, object=round_arch))


def test_the_battery_predicate_counts_its_terminals_kinds(suite: Suite) -> None:
    """Two studs 12.7 mm apart (the socket replaced by a second stud) pass the sizes and the distance but
    not the kinds' count: the battery's predicate rejects every frame of them."""
    fam = suite.family("battery_9v_terminals")
    stimuli = fam.scene.sensor.stimuli
    stud = stimuli.kinds[0]
    assert stud.kind == "punch" and stimuli.kinds[1].kind == "ring"
    assert_told_apart(stimuli, with_stimuli(fam, kinds=(stud, stud)))


def test_the_spectacles_predicate_sees_the_bridge(suite: Suite) -> None:
    """The same two rims touching (no bridge between them: 41-45 mm apart) are another object: the
    spectacles' predicate rejects every frame of them."""
    fam = suite.family("round_spectacles_face_down")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    touching = dataclasses.replace(stimuli.object, offsets_mm=((-21.5, 0.0), (21.5, 0.0)))
    assert_told_apart(stimuli, with_stimuli(fam, object=touching))


@pytest.mark.parametrize("reference", sorted(references()))
def test_no_reference_draws_a_frame_of_any_family(suite: Suite, reference: str) -> None:
    assert_no_frame_drawn(suite, reference, references()[reference], looks_like)


def test_every_family_but_the_single_contacts_is_an_object(suite: Suite) -> None:
    """The families of one contact are new by their shape alone; every other family places its
    contacts as the parts of one object (the arrangement the predicates check)."""
    assert_objects_but_the_single_contacts(suite, {"bubble_wand", "beach_ball"})
