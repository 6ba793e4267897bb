"""The strips16_unseen10 suite (unseen shapes, round 10): it parses, every family generates frames
within the sensor's range, and every family lies outside every strip scene in synth/scenes/, the OOD
suite and rounds 1-9, checked as rounds 4-9 check themselves: from the TOML files (counts, shapes,
arrangements) and in drawn frames (a predicate per family accepts its own frames and no frame of any
reference). The objects' parts are checked to fit together as the objects do (veins leaving the
midrib, bellows on the straw's bend, the frame's bars meeting in an L).

Written blind, before any model was evaluated on the suite: what this round can say is that no
*object* here is one a scene or an earlier round draws.
"""

from __future__ import annotations

import dataclasses
from functools import cache

import numpy as np
import pytest

from synth.scene import Scene, load_scene
from synth.sensors.strips.config import StimulusKind
from synth.suite import Suite, load_suite
from tests.synth.test_objects_scenes import draw
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
from tests.synth.test_unseen9_suite import references as round9_references
from tests.synth.test_unseen_suite import assert_frames_within_range

SUITE = "strips16_unseen10"
ROUND_9 = "strips16_unseen9"
EARLIER_ROUNDS = rounds_through(9)


@cache
def references() -> dict[str, Scene]:
    """Round 9's references (every strip scene, the OOD suite, rounds 1-8), round 9's families, and any
    strip scene added since."""
    return references_with(round9_references(), ROUND_9)


def middle(spec: StimulusKind, name: str) -> float:
    """The middle of one of an entry's ranges (a part's nominal size)."""
    lo, hi = getattr(spec, name)
    return (lo + hi) / 2


def direction(angle_deg: float) -> np.ndarray:
    return np.array([np.cos(np.deg2rad(angle_deg)), np.sin(np.deg2rad(angle_deg))])


@pytest.fixture(scope="module")
def suite() -> Suite:
    return load_suite(SUITE)


def test_suite_parses_with_its_families_described(suite: Suite) -> None:
    assert_round_parses(suite, EARLIER_ROUNDS, references(), 11 + 13 + 12 + 12 + 12 + 12 + 12 + 12 + 12 + 12)


def test_every_family_lies_outside_every_strip_scene_the_ood_suite_and_rounds_1_to_9(suite: Suite) -> None:
    assert_outside(suite, references())


def test_the_novelty_check_can_fail(suite: Suite) -> None:
    """The same object on both sides is no reason; the photo frame is new to the wide scene by its bars'
    size and its arrangement, bars of the wide scene's sizes are new by the arrangement alone, and placed
    independently they are two pads it draws; the jigsaw piece's tabs are new by having no hole, which
    tabs with a hole lose; the cricket ball's dome alone is a dome round 4's spoon bowl draws: the ball
    is new by its seam."""
    wide = load_scene("strips16_wide").sensor.stimuli
    frame = suite.family("photo_frame_corner").scene.sensor.stimuli
    assert novelty(frame, frame) == []
    assert novelty(frame, wide) == ["block outside its ranges", "block outside its ranges", "parts of one object"]
    narrow = tuple(dataclasses.replace(bar, width_mm=(10.0, 12.0), length_mm=(20.0, 28.0)) for bar in frame.kinds)
    assert novelty(dataclasses.replace(frame, kinds=narrow), wide) == ["parts of one object"]
    assert novelty(dataclasses.replace(frame, kinds=narrow, object=None), wide) == []
    piece = suite.family("jigsaw_corner_piece").scene.sensor.stimuli
    body, *tabs = piece.kinds
    assert novelty(piece, wide) == [
        "block outside its ranges",
        "ring outside its ranges",
        "ring outside its ranges",
        "parts of one object",
    ]
    holed = tuple(dataclasses.replace(tab, hole_fraction=(0.3, 0.3)) for tab in tabs)
    assert novelty(dataclasses.replace(piece, kinds=(body, *holed)), wide) == [
        "block outside its ranges",
        "parts of one object",
    ]
    ball = suite.family("cricket_ball_seam").scene.sensor.stimuli
    spoon = load_suite("strips16_unseen4").family("spoon_bowl").scene.sensor.stimuli
    assert novelty(ball, wide) == ["sphere outside its ranges", "parts of one object"]
    dome = dataclasses.replace(ball, count=(1, 1), kinds=ball.kinds[:1], object=None)
    assert novelty(dome, spoon) == []
    assert novelty(ball, spoon)[0] == "[3] contacts (reference: [1])"


def test_every_family_generates_frames_within_the_sensors_range(suite: Suite) -> None:
    # well below the ADC's full scale (the strongest of the six frames a family: the cricket ball, 0.32 of it)
    assert_frames_within_range(suite, full_scale_share=0.5)


def test_each_familys_predicate_accepts_its_own_frames(suite: Suite) -> None:
    assert_own_frames_accepted_by(suite, looks_like)


def test_the_leafs_veins_leave_its_midrib(suite: Suite) -> None:
    """At nominal sizes every side vein starts on the midrib (within 0.2 mm), three on each side, 9 mm
    apart along it and the two sides 3 mm out of step, all slanting towards the tip at 42 degrees."""
    stimuli = suite.family("beech_leaf_veins").scene.sensor.stimuli
    assert stimuli.object is not None
    midrib, *veins = stimuli.kinds
    assert midrib.angle_deg == (0.0, 0.0) and all(v.kind == "edge" for v in veins)
    starts = []
    for offset, vein in zip(stimuli.object.offsets_mm[1:], veins, strict=True):
        angle = middle(vein, "angle_deg")
        # the end nearer the midrib, which lies along y = 0
        end = np.asarray(offset) - middle(vein, "length_mm") / 2 * direction(angle) * np.sign(offset[1])
        assert abs(end[1]) < 0.2
        slant = np.rad2deg(np.arctan2(offset[1] - end[1], offset[0] - end[0]))
        assert np.isclose(abs(slant), 42.0, atol=0.05) and np.isclose(slant % 180, angle, atol=0.05)
        starts.append((float(np.sign(offset[1])), float(end[0])))
    upper = sorted(x for side, x in starts if side > 0)
    lower = sorted(x for side, x in starts if side < 0)
    assert len(upper) == len(lower) == 3
    assert np.allclose(np.diff(upper), 9.0, atol=0.02) and np.allclose(np.diff(lower), 9.0, atol=0.02)
    assert np.allclose(np.subtract(lower, upper), 3.0, atol=0.02)


def test_the_straws_bellows_lie_on_its_bend(suite: Suite) -> None:
    """The five ridges lie on an arc of 7.5 mm radius, each across the straw (radial); the two tubes'
    lines meet the arc's ends at right angles to its radius (tangentially), within 1 mm of them."""
    stimuli = suite.family("bendy_straw_elbow").scene.sensor.stimuli
    assert stimuli.object is not None
    offsets = np.asarray(stimuli.object.offsets_mm)
    long, short, *ridges = stimuli.kinds
    # the bend's centre: where the tubes' centre lines, each 7.5 mm from it, cross at right angles
    centre = np.array([offsets[1, 0] - 7.5, offsets[0, 1] + 7.5])
    radii = np.hypot(*(offsets[2:] - centre).T)
    assert np.allclose(radii, 7.5, atol=0.01)
    bearings = np.rad2deg(np.arctan2(*(offsets[2:] - centre).T[::-1])) % 180
    assert np.allclose(bearings, [middle(r, "angle_deg") for r in ridges], atol=0.1)
    assert long.angle_deg == (0.0, 0.0) and short.angle_deg == (90.0, 90.0)
    long_end = offsets[0] + middle(long, "length_mm") / 2 * direction(0.0)
    short_end = offsets[1] - middle(short, "length_mm") / 2 * direction(90.0)
    assert np.hypot(*(long_end - centre - np.array([0.0, -7.5]))) < 1.0
    assert np.hypot(*(short_end - centre - np.array([7.5, 0.0]))) < 1.0


def test_the_frames_bars_meet_in_an_l(suite: Suite) -> None:
    """At nominal sizes the two bars of moulding, equally wide, abut (no overlap, no gap over 0.5 mm) and
    share their outer edges, and both reach more than 20 mm past the frame's inner corner, leaving the
    opening beyond it empty; in drawn frames that corner lies on the array nine times in ten."""
    fam = suite.family("photo_frame_corner")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    rects = []
    for (x, y), bar in zip(stimuli.object.offsets_mm, stimuli.kinds, strict=True):
        half_along, half_across = middle(bar, "length_mm") / 2, middle(bar, "width_mm") / 2
        hx, hy = (half_along, half_across) if bar.angle_deg == (0.0, 0.0) else (half_across, half_along)
        rects.append((x - hx, x + hx, y - hy, y + hy))
    (ax0, ax1, ay0, ay1), (bx0, bx1, by0, by1) = rects
    assert abs(by0 - ay1) < 0.5 and abs(bx0 - ax0) < 0.5 and np.isclose(ay1 - ay0, bx1 - bx0)
    inner = np.array([bx1, ay1])  # from the object's centre, the middle of the two bars' centres
    assert ax1 > inner[0] + 20 and by1 > inner[1] + 20
    assert np.allclose(np.mean(stimuli.object.offsets_mm, axis=0), 0.0)
    c, _ = draw(fam.scene, 2000, seed=5)
    turn = np.deg2rad(c["angle_deg"][:, 0])  # the first bar lies along the object's x axis
    x = c["x_mm"][:, :2].mean(axis=1) + np.cos(turn) * inner[0] - np.sin(turn) * inner[1]
    y = c["y_mm"][:, :2].mean(axis=1) + np.sin(turn) * inner[0] + np.cos(turn) * inner[1]
    g = fam.scene.sensor.geometry
    on = (x >= 0) & (x <= g.n_cols * g.pitch_mm) & (y >= 0) & (y <= g.n_rows * g.pitch_mm)
    assert 0.8 < on.mean() < 0.95


def test_a_corner_piece_predicate_tells_it_from_a_middle_piece(suite: Suite) -> None:
    """The same body with its two tabs on opposite sides (a piece from the middle of a row) is another
    piece: the corner piece's predicate rejects every frame of it."""
    fam = suite.family("jigsaw_corner_piece")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    opposite = dataclasses.replace(stimuli.object, offsets_mm=((0.0, 0.0), (12.0, 0.0), (-12.0, 0.0)))
    assert_told_apart(stimuli, with_stimuli(fam, object=opposite))


def test_a_lattice_predicate_tells_the_bath_mat_from_another_grid(suite: Suite) -> None:
    """A mat whose small cups sit between the large ones along the middle row and column (the large
    cups 18.8-19.6 mm apart to make room for them) is another mat: the bath mat's predicate rejects
    every frame of it."""
    fam = suite.family("bath_mat_suction_cups")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    large = tuple((2.0 * i, 2.0 * j) for j in (-1, 0, 1) for i in (-1, 0, 1))
    small = ((0.0, -1.0), (-1.0, 0.0), (1.0, 0.0), (0.0, 1.0))
    plus = dataclasses.replace(stimuli.object, offsets_mm=(*large, *small), scale=(9.4, 9.8))
    assert_told_apart(stimuli, with_stimuli(fam, object=plus, margin_mm=-8.0))


def test_the_leaf_predicate_sees_its_veins_out_of_step(suite: Suite) -> None:
    """The same veins in opposite pairs (both sides leaving the midrib at the same points) are another
    leaf: the beech leaf's predicate rejects every frame of it."""
    fam = suite.family("beech_leaf_veins")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    midrib, *upper, _, _, _ = stimuli.object.offsets_mm
    paired = (midrib, *upper, *((x, -y) for x, y in upper))
    assert_told_apart(stimuli, with_stimuli(fam, object=dataclasses.replace(stimuli.object, offsets_mm=paired)))


@pytest.mark.parametrize("reference", sorted(references()))
def test_no_reference_draws_a_frame_of_any_family(suite: Suite, reference: str) -> None:
    assert_no_frame_drawn(suite, reference, references()[reference], looks_like)


def test_every_family_but_the_single_contacts_is_an_object(suite: Suite) -> None:
    """No family here is a single contact: every family places its contacts as the parts of one object
    (the arrangement the predicates check)."""
    assert_objects_but_the_single_contacts(suite, set())
