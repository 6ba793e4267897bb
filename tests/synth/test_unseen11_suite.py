"""The strips16_unseen11 suite (unseen shapes, round 11): it parses, every family generates frames
within the sensor's range, and every family lies outside every strip scene in synth/scenes/, the OOD
suite and rounds 1-10, checked as rounds 4-10 check themselves: from the TOML files (counts, shapes,
arrangements) and in drawn frames (a predicate per family accepts its own frames and no frame of any
reference). The objects' parts are checked to fit together as the objects do (a staple's legs at its
crown's ends, a hinge's leaves against its barrel, a hook's wire in one piece, the ammonite's whorls on
one spiral, the rosette's leaves at the golden angle, the cross-stitches at the holes of the weave).

Written blind, before any model was evaluated on the suite: what this round can say is that no
*object* here is one a scene or an earlier round draws.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence
from functools import cache

import numpy as np
import pytest

from synth.scene import Scene, load_scene
from synth.sensors.strips.config import StimulusKind, StripStimuli
from synth.suite import Family, Suite, load_suite
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
from tests.synth.test_unseen10_suite import direction, middle
from tests.synth.test_unseen10_suite import references as round10_references
from tests.synth.test_unseen_suite import assert_frames_within_range

SUITE = "strips16_unseen11"
ROUND_10 = "strips16_unseen10"
EARLIER_ROUNDS = rounds_through(10)
#: the square of 6-count Aida cloth (mm): six stitches to the inch
AIDA_MM = 25.4 / 6
#: the golden angle (degrees), between successive leaves of a rosette
GOLDEN_DEG = 137.5


@cache
def references() -> dict[str, Scene]:
    """Round 10's references (every strip scene, the OOD suite, rounds 1-9), round 10's families, and any
    strip scene added since."""
    return references_with(round10_references(), ROUND_10)


def ends(offset: np.ndarray, spec: StimulusKind) -> np.ndarray:
    """The two ends (2, 2) of a line or pad part at its offset, at nominal length."""
    half = middle(spec, "length_mm") / 2 * direction(middle(spec, "angle_deg"))
    return np.array([offset - half, offset + half])


def object_parts(stimuli: StripStimuli) -> tuple[np.ndarray, tuple[StimulusKind, ...]]:
    """The offsets (K, 2) of an object's parts and their entries."""
    assert stimuli.object is not None and stimuli.object.part_kinds
    return np.asarray(stimuli.object.offsets_mm, dtype=np.float64), stimuli.kinds


@pytest.fixture(scope="module")
def suite() -> Suite:
    return load_suite(SUITE)


def test_suite_parses_with_its_families_described(suite: Suite) -> None:
    assert_round_parses(suite, EARLIER_ROUNDS, references(), 11 + 13 + 12 + 12 + 12 + 12 + 12 + 12 + 12 + 12 + 12)


def test_every_family_lies_outside_every_strip_scene_the_ood_suite_and_rounds_1_to_10(suite: Suite) -> None:
    assert_outside(suite, references())


def test_the_novelty_check_can_fail(suite: Suite) -> None:
    """The same object on both sides is no reason; the coat button is new to the wide scene by its
    arrangement alone (its rim and stitches placed independently are a ring and two lines it draws);
    the hinge has round 4's watch's arrangement (a middle part between two mirror-image pads) and is new
    to it by its parts alone, which the watch's own parts lose; the toy spider's feet are the size of
    round 3's comb teeth and new to it by their count and arrangement."""
    wide = load_scene("strips16_wide").sensor.stimuli
    button = suite.family("sewn_coat_button").scene.sensor.stimuli
    assert novelty(button, button) == []
    assert novelty(button, wide) == ["parts of one object"]
    assert novelty(dataclasses.replace(button, object=None), wide) == []
    hinge = suite.family("butt_hinge_lying_open").scene.sensor.stimuli
    watch = load_suite("strips16_unseen4").family("watch_on_its_back").scene.sensor.stimuli
    assert novelty(hinge, watch) == ["edge outside its ranges", "block outside its ranges", "block outside its ranges"]
    assert novelty(dataclasses.replace(hinge, kinds=watch.kinds), watch) == []
    spider = suite.family("rubber_toy_spider").scene.sensor.stimuli
    comb = load_suite("strips16_unseen3").family("comb_teeth").scene.sensor.stimuli
    assert novelty(spider, comb) == ["[8] contacts (reference: [12])", "another arrangement"]


def test_every_family_generates_frames_within_the_sensors_range(suite: Suite) -> None:
    # well below the ADC's full scale (the strongest of the six frames a family: the gingerbread man, 0.22)
    assert_frames_within_range(suite, full_scale_share=0.5)


def test_each_familys_predicate_accepts_its_own_frames(suite: Suite) -> None:
    assert_own_frames_accepted_by(suite, looks_like)


#: the mirror-image parts (pairs of part indices) of the objects that have a mirror line (their x = 0)
MIRROR_PAIRS = {
    "sewn_coat_button": ((2, 1),),
    "butt_hinge_lying_open": ((1, 2),),
    "office_staple": ((2, 1),),
    "puckered_lips": ((0, 1),),
    "rubber_toy_spider": ((0, 1), (2, 3), (4, 5), (6, 7)),
    "gingerbread_man": ((2, 3), (4, 5)),
    "dwarf_hamster": ((0, 1), (2, 3)),
}


@pytest.mark.parametrize("name", sorted(MIRROR_PAIRS))
def test_the_symmetric_objects_are_mirror_images(suite: Suite, name: str) -> None:
    """Each pair's parts lie mirrored in the object's line x = 0 and are one entry but for a mirrored
    angle (a left and a right leg, arm, leaf of a hinge); every other part lies on that line."""
    stimuli = suite.family(name).scene.sensor.stimuli
    assert stimuli.object is not None
    offsets = np.asarray(stimuli.object.offsets_mm)
    paired = [i for pair in MIRROR_PAIRS[name] for i in pair]
    for right, left in MIRROR_PAIRS[name]:
        assert np.allclose(offsets[left], offsets[right] * [-1, 1]) and offsets[right, 0] > 0
        if stimuli.object.part_kinds:
            lo, hi = stimuli.kinds[right].angle_deg
            assert stimuli.kinds[left] == dataclasses.replace(stimuli.kinds[right], angle_deg=(180 - hi, 180 - lo))
    on_the_line = [i for i in range(len(offsets)) if i not in paired]
    assert np.allclose(offsets[on_the_line, 0], 0.0)


def test_the_buttons_stitches_lie_in_its_hole(suite: Suite) -> None:
    """At nominal sizes the two bundles of thread are parallel, 5 mm apart (the holes' pitch) and shorter
    than it, and wholly inside the rim's hole with 4 mm to spare."""
    rim, *stitches = suite.family("sewn_coat_button").scene.sensor.stimuli.kinds
    offsets, _ = object_parts(suite.family("sewn_coat_button").scene.sensor.stimuli)
    hole = middle(rim, "radius_mm") * middle(rim, "hole_fraction")
    assert rim.kind == "ring" and np.allclose(offsets[0], 0.0)
    assert stitches[0].angle_deg == stitches[1].angle_deg and np.hypot(*(offsets[1] - offsets[2])) == 5.0
    for offset, stitch in zip(offsets[1:], stitches, strict=True):
        assert middle(stitch, "length_mm") < 5.0 and np.hypot(*ends(offset, stitch).T).max() < hole - 4.0


def test_the_hinges_leaves_lie_against_its_barrel_and_press_at_their_outer_edges(suite: Suite) -> None:
    """At nominal sizes each leaf's inner edge lies at the barrel's surface (within 0.1 mm), the leaves
    are as long as the barrel, and each leaf's pressure rises towards its outer edge (its slope along
    its angle, which points away from the barrel)."""
    offsets, (barrel, *leaves) = object_parts(suite.family("butt_hinge_lying_open").scene.sensor.stimuli)
    assert barrel.kind == "edge" and np.allclose(offsets[0], 0.0) and barrel.angle_deg == (90.0, 90.0)
    for offset, leaf in zip(offsets[1:], leaves, strict=True):
        assert abs(np.hypot(*offset) - middle(leaf, "length_mm") / 2 - middle(barrel, "radius_mm")) < 0.1
        assert middle(leaf, "width_mm") == middle(barrel, "length_mm") and offset[1] == 0.0
        assert leaf.tilt[0] > 0 and direction(middle(leaf, "angle_deg")) @ offset > 0


def test_the_staples_legs_hang_from_the_ends_of_its_crown(suite: Suite) -> None:
    """At nominal sizes each leg's top lies at an end of the crown (within 0.1 mm), square to it, and
    both legs hang on one side of it: a U 12 mm across."""
    offsets, (crown, *legs) = object_parts(suite.family("office_staple").scene.sensor.stimuli)
    assert crown.angle_deg == (0.0, 0.0) and offsets[0, 1] == 0.0
    crown_ends = ends(offsets[0], crown)
    for offset, leg, corner in zip(offsets[1:], legs, crown_ends, strict=True):
        assert leg.angle_deg == (90.0, 90.0)
        bottom, top = ends(offset, leg)
        assert np.hypot(*(top - corner)) < 0.1 and bottom[1] < -5.0


def test_the_razors_blades_lie_between_its_guard_and_its_strip(suite: Suite) -> None:
    """At nominal sizes every part is parallel; the three blades are 1.6 mm apart, the guard lies in
    front of them and the lubricating strip behind, each clear of the nearest blade."""
    offsets, (guard, *blades, strip) = object_parts(suite.family("razor_cartridge").scene.sensor.stimuli)
    assert all(part.angle_deg == (0.0, 0.0) for part in (guard, *blades, strip)) and np.allclose(offsets[:, 0], 0)
    assert [b.kind for b in blades] == ["edge"] * 3 and np.allclose(np.diff(offsets[1:4, 1]), 1.6)
    assert offsets[0, 1] + middle(guard, "width_mm") / 2 < offsets[1, 1] - 0.5
    assert offsets[4, 1] - middle(strip, "width_mm") / 2 > offsets[3, 1] + 0.5


def test_the_cross_stitches_meet_at_the_holes_of_the_weave(suite: Suite) -> None:
    """Turned back into the cloth's frame, the crosses stand on whole squares of the Aida, four, three
    and one in the heart's rows with a gap in the middle of the top one; each cross is two stitches at
    right angles on its square's centre, every stitch ends at holes of the weave (within 0.05 of a
    square), and neighbouring crosses share their holes."""
    offsets, stitches = object_parts(suite.family("cross_stitched_heart").scene.sensor.stimuli)
    turn = np.array([[1.0, -1.0], [1.0, 1.0]]) / np.sqrt(2)  # the stitches' frame back to the cloth's
    cells = offsets @ turn.T / AIDA_MM
    assert np.allclose(cells, np.round(cells), atol=1e-3)
    squares = {tuple(int(v) for v in np.round(c)) for c in cells}
    assert squares == {(-2, 1), (-1, 1), (1, 1), (2, 1), (-1, 0), (0, 0), (1, 0), (0, -1)}
    assert np.allclose(offsets[0::2], offsets[1::2])
    assert all(s.angle_deg == (0.0, 0.0) for s in stitches[0::2])
    assert all(s.angle_deg == (90.0, 90.0) for s in stitches[1::2])
    holes = np.concatenate([ends(offset, stitch) for offset, stitch in zip(offsets, stitches, strict=True)])
    holes = holes @ turn.T / AIDA_MM - 0.5
    assert np.allclose(holes, np.round(holes), atol=0.05)
    assert len({tuple(h) for h in np.round(holes).astype(int)}) < len(holes)


def test_the_ammonites_whorls_lie_on_one_logarithmic_spiral(suite: Suite) -> None:
    """At nominal sizes the fourteen pieces join end to end (within 0.05 mm) into one line whose corners
    turn 45 degrees about the centre each and lie on a logarithmic spiral, the radius halving every turn
    inwards; each piece's tip radius is a fifth of its distance from the centre (within 10 %)."""
    offsets, pieces = object_parts(suite.family("ammonite_fossil").scene.sensor.stimuli)
    first = ends(offsets[0], pieces[0])
    corners = list(first[np.argsort(-np.hypot(*first.T))])
    for offset, piece in zip(offsets[1:], pieces[1:], strict=True):
        start, end = sorted(ends(offset, piece), key=lambda p: float(np.hypot(*(p - corners[-1]))))
        assert np.hypot(*(start - corners[-1])) < 0.05
        corners.append(end)
    radii = np.hypot(*np.transpose(corners))
    assert np.allclose(radii[1:] / radii[:-1], 2 ** (-1 / 8), rtol=0.01)
    bearings = np.rad2deg(np.arctan2(*np.transpose(corners)[::-1]))
    assert np.allclose((np.diff(bearings) + 180) % 360 - 180, -45.0, atol=0.1)
    for offset, piece in zip(offsets, pieces, strict=True):
        mean_radius = np.hypot(*ends(offset, piece).T).mean()
        assert 0.18 * 0.9 < middle(piece, "radius_mm") / mean_radius < 0.22 * 1.1


def test_the_fishing_hook_is_one_wire(suite: Suite) -> None:
    """At nominal sizes the shank hangs from the eye's rim, its foot and the point's foot are the ends of
    a half circle of 5 mm radius on which the bend's four pieces join end to end (within 0.05 mm), the
    point runs parallel to the shank 10 mm from it, and the barb leaves the point near its tip, pointing
    back towards the bend and in towards the shank."""
    offsets, (eye, shank, *bend, point, barb) = object_parts(suite.family("fishing_hook").scene.sensor.stimuli)
    assert eye.kind == "ring" and len(bend) == 4 and shank.angle_deg == point.angle_deg == (90.0, 90.0)
    shank_foot, shank_top = ends(offsets[1], shank)
    assert np.hypot(*(offsets[0] - [0.0, middle(eye, "radius_mm")] - shank_top)) < 0.1
    point_foot, point_tip = ends(offsets[6], point)
    centre, radius = (shank_foot + point_foot) / 2, np.hypot(*(point_foot - shank_foot)) / 2
    assert radius == pytest.approx(5.0, abs=0.05) and point_foot[0] - shank_foot[0] == pytest.approx(10.0)
    corner = shank_foot
    for offset, piece in zip(offsets[2:6], bend, strict=True):
        start, end = sorted(ends(offset, piece), key=lambda p: float(np.hypot(*(p - corner))))
        assert np.hypot(*(start - corner)) < 0.05 and abs(np.hypot(*(end - centre)) - radius) < 0.05
        assert end[1] < centre[1] + 1e-9
        corner = end
    assert np.hypot(*(corner - point_foot)) < 0.05
    root, barb_tip = sorted(ends(offsets[7], barb), key=lambda p: -float(p[0]))
    assert abs(root[0] - point_tip[0]) < 0.05 and point_tip[1] - root[1] < 2.0
    assert barb_tip[1] < root[1] and barb_tip[0] < root[0]


def test_the_gingerbread_mans_head_and_limbs_join_his_body(suite: Suite) -> None:
    """At nominal sizes the head sits on the body's top edge (within 0.1 mm); every limb starts inside
    the body's outline and ends outside it, the arms rising and the legs falling away from it; the
    icing buttons lie down the body's middle, wholly on it."""
    offsets, (head, body, *limbs) = object_parts(suite.family("gingerbread_man").scene.sensor.stimuli)
    limbs, buttons = limbs[:4], limbs[4:]
    assert body.angle_deg == (90.0, 90.0) and np.allclose(offsets[1], 0.0)
    half_width, half_height = middle(body, "width_mm") / 2, middle(body, "length_mm") / 2

    def inside(p: np.ndarray, margin: float = 0.0) -> bool:
        return abs(p[0]) < half_width - margin and abs(p[1]) < half_height - margin

    assert offsets[0, 1] - middle(head, "radius_mm") == pytest.approx(half_height, abs=0.1)
    for k, (offset, limb) in enumerate(zip(offsets[2:6], limbs, strict=True)):
        root, tip = sorted(ends(offset, limb), key=lambda p: float(np.hypot(*p)))
        assert inside(root) and not inside(tip)
        assert (tip[1] > root[1]) if k < 2 else (tip[1] < root[1] - 10.0)
    for offset, button in zip(offsets[6:], buttons, strict=True):
        assert button.kind == "sphere" and offset[0] == 0.0 and inside(offset, middle(button, "radius_mm"))


def test_the_rosettes_leaves_follow_the_golden_angle(suite: Suite) -> None:
    """Each leaf lies 137.5 degrees round from the one before, its middle as far from the centre as the
    square root of its order; every leaf points straight out from the centre and presses harder
    towards its tip (its slope's sign turns its angle outwards), and the leaves grow outwards."""
    offsets, leaves = object_parts(suite.family("echeveria_rosette").scene.sensor.stimuli)
    bearings = np.rad2deg(np.arctan2(offsets[:, 1], offsets[:, 0]))
    assert np.allclose(np.diff(bearings) % 360, GOLDEN_DEG, atol=0.05)
    distances = np.hypot(*offsets.T)
    assert np.allclose(distances / np.sqrt(np.arange(1, 14)), distances[0], rtol=0.002)
    for bearing, leaf in zip(bearings, leaves, strict=True):
        outwards = middle(leaf, "angle_deg") + (0.0 if leaf.tilt[0] > 0 else 180.0)
        assert np.cos(np.deg2rad(outwards - bearing)) == pytest.approx(1.0) and leaf.tilt[0] * leaf.tilt[1] > 0
    assert (np.diff([middle(leaf, "length_mm") for leaf in leaves]) > 0).all()
    assert (np.diff([middle(leaf, "width_mm") for leaf in leaves]) > 0).all()


def assert_told_apart_with_parts_at(fam: Family, offsets: Iterable[Sequence[float]]) -> None:
    """The family's object with its parts moved to ``offsets`` (mm, rounded to the micrometre, as a suite
    file writes them) is another object: the family's predicate rejects every frame of it."""
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    placed = tuple((round(float(x), 3), round(float(y), 3)) for x, y in offsets)
    assert_told_apart(stimuli, with_stimuli(fam, object=dataclasses.replace(stimuli.object, offsets_mm=placed)))


def test_a_stance_predicate_tells_the_spider_from_a_ring_of_feet(suite: Suite) -> None:
    """The same eight feet evenly round a circle of 21 mm radius (no body's axis, no front or back) are
    another object: the toy spider's predicate rejects every frame of it."""
    fam = suite.family("rubber_toy_spider")
    angles = np.deg2rad(np.arange(8) * 45.0 + 22.5)
    assert_told_apart_with_parts_at(fam, [(21 * float(np.cos(a)), 21 * float(np.sin(a))) for a in angles])


def test_the_heart_predicate_sees_the_picture(suite: Suite) -> None:
    """The same eight crosses on a block of two rows of four squares are another picture: the heart's
    predicate rejects every frame of it."""
    fam = suite.family("cross_stitched_heart")
    squares = [(i, j) for j in (0.5, -0.5) for i in (-1.5, -0.5, 0.5, 1.5)]
    block = [((i + j) * AIDA_MM / np.sqrt(2), (j - i) * AIDA_MM / np.sqrt(2)) for i, j in squares for _ in range(2)]
    assert_told_apart_with_parts_at(fam, block)


def test_the_rosette_predicate_sees_the_golden_angle(suite: Suite) -> None:
    """The same leaves placed 144 degrees apart (two fifths of a turn, a Fibonacci ratio near the
    golden one) are another plant: the rosette's predicate rejects every frame of it."""
    fam = suite.family("echeveria_rosette")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    distances = np.hypot(*np.asarray(stimuli.object.offsets_mm).T)
    angles = np.deg2rad(np.arange(13) * 144.0)
    assert_told_apart_with_parts_at(fam, zip(distances * np.cos(angles), distances * np.sin(angles), strict=True))


def test_the_ammonite_predicate_sees_the_logarithmic_spiral(suite: Suite) -> None:
    """The same pieces on an Archimedean spiral (whorls evenly spaced, from the same outer to the same
    inner radius) are another shell: the ammonite's predicate rejects every frame of it."""
    fam = suite.family("ammonite_fossil")
    bearings = np.deg2rad(6.0 - 45.0 * np.arange(15))
    radii = np.linspace(16.0, 16.0 * 2 ** (-14 / 8), 15)
    corners = np.stack([radii * np.cos(bearings), radii * np.sin(bearings)], axis=-1)
    assert_told_apart_with_parts_at(fam, (corners[1:] + corners[:-1]) / 2)


@pytest.mark.parametrize("reference", sorted(references()))
def test_no_reference_draws_a_frame_of_any_family(suite: Suite, reference: str) -> None:
    assert_no_frame_drawn(suite, reference, references()[reference], looks_like)


def test_every_family_but_the_single_contacts_is_an_object(suite: Suite) -> None:
    """No family here is a single contact: every family places its contacts as the parts of one object
    (the arrangement the predicates check)."""
    assert_objects_but_the_single_contacts(suite, set())
