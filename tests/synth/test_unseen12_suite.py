"""The strips16_unseen12 suite (unseen shapes, round 12): it parses, every family generates frames
within the sensor's range, and every family lies outside every strip scene in synth/scenes/, the OOD
suite and rounds 1-11, checked as rounds 4-11 check themselves: from the TOML files (counts, shapes,
arrangements) and in drawn frames (a predicate per family accepts its own frames and no frame of any
reference). The objects' parts are checked to fit together as the objects do (a fusilli's crests where
its flights cross its lowest line, a scallop's ribs fanning from its umbo, a bobby pin's crimped leg one
wire against its straight leg, a plait's lobes as chevrons, a cookie's chips scattered on its top, a
starfish's five arms, a bobbin's flanges at its thread's ends, a track's lands ending at its peg, a
leek's layers each touching the one outside it, a floss pick's thread between its arms' tips, a
ravioli's border a closed frame, a cone's radius growing from its tip).

Written blind, before any model was evaluated on the suite: what this round can say is that no
*object* here is one a scene or an earlier round draws.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Sequence
from functools import cache

import numpy as np
import pytest

from synth.scene import Scene, load_scene
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
from tests.synth.test_unseen11_suite import ends, object_parts
from tests.synth.test_unseen11_suite import references as round11_references
from tests.synth.test_unseen_suite import assert_frames_within_range

SUITE = "strips16_unseen12"
ROUND_11 = "strips16_unseen11"
EARLIER_ROUNDS = rounds_through(11)
#: a fusilli's crest radius (mm), its flights' pitch (mm) and their number
FUSILLI_RADIUS_MM, FUSILLI_PITCH_MM, FUSILLI_FLIGHTS = 5.0, 18.0, 3
#: the scallop's flattened oval: its half-widths across and along the shell (mm), its centre's distance
#: from the umbo (mm), and the ribs' spacing (degrees)
OVAL_MM, OVAL_FROM_UMBO_MM, RIB_STEP_DEG = (22.0, 11.0), 30.0, 8.0
#: the sugar cone's slant from tip to rim and its rim's radius (mm)
CONE_SLANT_MM, CONE_RIM_MM = 48.0, 13.0


@cache
def references() -> dict[str, Scene]:
    """Round 11's references (every strip scene, the OOD suite, rounds 1-10), round 11's families, and any
    strip scene added since."""
    return references_with(round11_references(), ROUND_11)


def perpendicular(angle_deg: float) -> np.ndarray:
    """The unit vector a quarter turn anticlockwise from ``angle_deg``."""
    return direction(angle_deg + 90.0)


def moved(fam: Family, offsets: Sequence[tuple[float, float]], **changes: object) -> Scene:
    """The family's scene with its object's parts moved to ``offsets`` (and other stimuli fields changed)."""
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    placed = tuple((round(float(x), 3), round(float(y), 3)) for x, y in offsets)
    return with_stimuli(fam, object=dataclasses.replace(stimuli.object, offsets_mm=placed), **changes)


@pytest.fixture(scope="module")
def suite() -> Suite:
    return load_suite(SUITE)


def test_suite_parses_with_its_families_described(suite: Suite) -> None:
    assert_round_parses(suite, EARLIER_ROUNDS, references(), 11 + 13 + 12 * 10)


def test_every_family_lies_outside_every_strip_scene_the_ood_suite_and_rounds_1_to_11(suite: Suite) -> None:
    assert_outside(suite, references())


def test_the_novelty_check_can_fail(suite: Suite) -> None:
    """The same object on both sides is no reason; the fusilli's crests are edges the wide scene draws,
    and it is new to it by their arrangement alone (placed independently they are six edges it draws);
    it has round 3's key's arrangement (six crests in a row, evenly spaced) and is new to the key by its
    crests alone, which the key's own ridges lose; the leek's two outer layers are thin rims the wide
    scene holds out, its inner four rings it draws; the cookie's top alone is a disc round 5's tumbler
    base draws: the cookie is new by its chips."""
    wide = load_scene("strips16_wide").sensor.stimuli
    fusilli = suite.family("fusilli_pasta").scene.sensor.stimuli
    assert novelty(fusilli, fusilli) == []
    assert novelty(fusilli, wide) == ["parts of one object"]
    assert novelty(dataclasses.replace(fusilli, object=None), wide) == []
    key = load_suite("strips16_unseen3").family("key_teeth").scene.sensor.stimuli
    assert novelty(fusilli, key) == ["edge outside its ranges"] * 6
    assert novelty(dataclasses.replace(fusilli, kinds=key.kinds * 6), key) == []
    leek = suite.family("leek_slice_rings").scene.sensor.stimuli
    assert novelty(leek, wide) == ["ring outside its ranges"] * 2 + ["parts of one object"]
    inner = dataclasses.replace(leek, count=(4, 4), kinds=leek.kinds[2:], object=None)
    assert novelty(inner, wide) == []
    cookie = suite.family("chocolate_chip_cookie").scene.sensor.stimuli
    tumbler = load_suite("strips16_unseen5").family("tumbler_base").scene.sensor.stimuli
    assert novelty(cookie, tumbler) == [
        "[8] contacts (reference: [1])",
        *["sphere outside its ranges"] * 7,
        "parts of one object",
    ]
    top = dataclasses.replace(cookie, count=(1, 1), kinds=cookie.kinds[:1], object=None)
    assert novelty(top, tumbler) == []


def test_every_family_generates_frames_within_the_sensors_range(suite: Suite) -> None:
    # well below the ADC's full scale (the strongest of the six frames a family: the cookie, 0.26 of it)
    assert_frames_within_range(suite, full_scale_share=0.5)


def test_each_familys_predicate_accepts_its_own_frames(suite: Suite) -> None:
    assert_own_frames_accepted_by(suite, looks_like)


#: the mirror-image parts (pairs of part indices, the right one first) of the objects that have a mirror
#: line (their x = 0); the leek and the cone lie wholly on theirs
MIRROR_PAIRS = {
    "scallop_shell_ribs": ((1, 2), (3, 4), (5, 6), (7, 8)),
    "dried_starfish": ((1, 2), (3, 5), (4, 6), (7, 9), (8, 10)),
    "sewing_machine_bobbin": ((1, 2),),
    "wooden_train_track_end": ((0, 2),),
    "leek_slice_rings": (),
    "dental_floss_pick": ((1, 2),),
    "ravioli_parcel": ((3, 4),),
    "ice_cream_cone_on_its_side": (),
}


@pytest.mark.parametrize("name", sorted(MIRROR_PAIRS))
def test_the_symmetric_objects_are_mirror_images(suite: Suite, name: str) -> None:
    """Each pair's parts lie mirrored in the object's line x = 0 and are one entry but for a mirrored
    angle (180 degrees less the right one's: a left and a right rib, ridge, flange, land, arm, strip);
    every other part lies on that line."""
    offsets, kinds = object_parts(suite.family(name).scene.sensor.stimuli)
    for right, left in MIRROR_PAIRS[name]:
        assert np.allclose(offsets[left], offsets[right] * [-1, 1]) and offsets[right, 0] > 0
        lo, hi = kinds[right].angle_deg
        assert kinds[left] == dataclasses.replace(kinds[right], angle_deg=(180 - hi, 180 - lo))
    paired = {i for pair in MIRROR_PAIRS[name] for i in pair}
    assert np.allclose([offsets[i, 0] for i in range(len(offsets)) if i not in paired], 0.0)


def test_the_fusillis_crests_lie_where_its_flights_cross_its_lowest_line(suite: Suite) -> None:
    """The six crests lie on one line, a third of the flights' 18 mm pitch apart, all parallel at the
    helix angle atan(2 pi r / pitch) = 60.2 degrees to it (r = 5 mm); each is as long as the stretch
    2 sqrt(2 rho d) over which a crest curved along its length (rho = (r^2 + c^2) / r, c = pitch / 2 pi)
    presses d = 0.2-0.3 mm into the cover (within 0.1 mm)."""
    offsets, crests = object_parts(suite.family("fusilli_pasta").scene.sensor.stimuli)
    assert np.allclose(offsets[:, 1], 0.0)
    assert np.allclose(np.diff(offsets[:, 0]), FUSILLI_PITCH_MM / FUSILLI_FLIGHTS)
    helix = np.rad2deg(np.arctan(2 * np.pi * FUSILLI_RADIUS_MM / FUSILLI_PITCH_MM))
    lead = FUSILLI_PITCH_MM / (2 * np.pi)
    rho = (FUSILLI_RADIUS_MM**2 + lead**2) / FUSILLI_RADIUS_MM
    pressed = tuple(2 * np.sqrt(2 * rho * d) for d in (0.2, 0.3))
    for crest in crests:
        assert crest.kind == "edge" and crest.angle_deg == crests[0].angle_deg
        assert middle(crest, "angle_deg") == pytest.approx(helix, abs=0.05)
        assert crest.length_mm == pytest.approx(pressed, abs=0.1)


def test_the_scallops_ribs_fan_out_from_its_umbo_across_one_oval(suite: Suite) -> None:
    """At nominal sizes the nine ribs' lines meet at one point, the umbo (within 0.05 mm), 8 degrees
    apart; every rib's ends lie on the oval the valve flattens into (44 mm across and 22 mm along the
    shell, centred 30 mm from the umbo: within 0.01 of its equation), each rib its chord; the umbo lies
    outside the oval, so that no rib reaches it."""
    offsets, ribs = object_parts(suite.family("scallop_shell_ribs").scene.sensor.stimuli)
    angles = np.array([middle(rib, "angle_deg") for rib in ribs])
    # where each rib's line crosses the shell's axis (x = 0); the middle rib lies on it
    umbos = [offset[1] - offset[0] * np.tan(np.deg2rad(a)) for offset, a in zip(offsets[1:], angles[1:], strict=True)]
    umbo = np.array([0.0, np.mean(umbos)])
    assert np.allclose(umbos, umbo[1], atol=0.05) and angles[0] == 90.0 and offsets[0, 0] == 0.0
    assert np.allclose(np.sort(angles), 90.0 + RIB_STEP_DEG * np.arange(-4, 5))
    centre = umbo + np.array([0.0, OVAL_FROM_UMBO_MM])
    for offset, rib in zip(offsets, ribs, strict=True):
        for end in ends(offset, rib):
            assert np.sum(((end - centre) / OVAL_MM) ** 2) == pytest.approx(1.0, abs=0.01)
    assert OVAL_MM[1] < OVAL_FROM_UMBO_MM


def test_the_bobby_pins_crimped_leg_is_one_wire_against_its_straight_leg(suite: Suite) -> None:
    """At nominal sizes the crimped leg's root, six wave strips and flared end join end to end (within
    0.05 mm), the root starting level with the straight leg's end at the bend; where the waves come
    nearest the straight leg their centre line lies one wire's width from its centre line (the wires
    touch), 2 mm further at the crests; the end flares 1.5 mm further open; a tip caps each leg's end."""
    offsets, (leg, root, *waves, flare, leg_tip, crimped_tip) = object_parts(
        suite.family("bobby_pin").scene.sensor.stimuli
    )
    width = middle(leg, "width_mm")
    assert all(middle(part, "width_mm") == width for part in (root, *waves, flare))
    assert leg.angle_deg == root.angle_deg == (0.0, 0.0) and len(waves) == 6
    bend, leg_end = ends(offsets[0], leg)
    start, corner = ends(offsets[1], root)
    assert abs(start[0] - bend[0]) < 0.05
    gaps = [leg_end[1] - corner[1]]
    for offset, strip in zip(offsets[2:9], (*waves, flare), strict=True):
        near, far = sorted(ends(offset, strip), key=lambda p: float(np.hypot(*(p - corner))))
        assert np.hypot(*(near - corner)) < 0.05 and far[0] > near[0]
        corner = far
        gaps.append(leg_end[1] - corner[1])
    assert np.allclose(gaps, [width, width + 2, width, width + 2, width, width + 2, width, width + 1.5], atol=0.05)
    assert np.hypot(*(offsets[9] - leg_end)) < 0.05 and np.hypot(*(offsets[10] - corner)) < 0.05
    assert leg_tip.kind == crimped_tip.kind == "sphere"


def test_the_plaits_lobes_stack_as_chevrons_before_its_tie_and_tail(suite: Suite) -> None:
    """At nominal sizes the five lobes alternate sides of the plait's middle line, 6.5 mm apart along it,
    slanting 37 degrees either way so that each points to the plait's end (its inner end the nearer);
    each lobe's inner end reaches the middle line (within 0.5 mm) and its outer end lies within the
    plait's 18 mm width; the tie lies square across the middle line beyond every lobe, the tail
    beyond the tie."""
    offsets, (*lobes, tie, tail) = object_parts(suite.family("three_strand_plait").scene.sensor.stimuli)
    sides = np.sign(offsets[:5, 1])
    assert np.all(sides[1:] == -sides[:-1]) and np.allclose(np.diff(offsets[:5, 0]), 6.5)
    lobe_ends = []
    for offset, lobe, side in zip(offsets[:5], lobes, sides, strict=True):
        assert middle(lobe, "angle_deg") == (143.0 if side > 0 else 37.0)
        inner, outer = sorted(ends(offset, lobe), key=lambda p: abs(float(p[1])))
        assert abs(inner[1]) < 0.5 and abs(outer[1]) < 9.0 and inner[0] > outer[0]
        lobe_ends.append(inner[0])
    assert np.allclose(offsets[5:, 1], 0.0) and tie.angle_deg == (90.0, 90.0) and tail.kind == "blob"
    assert offsets[5, 0] - middle(tie, "radius_mm") > max(lobe_ends) and offsets[6, 0] > offsets[5, 0]


def test_the_cookies_chips_lie_scattered_on_its_top(suite: Suite) -> None:
    """At nominal sizes every chip lies wholly on the cookie, at least 8 mm inside its rim, and no two
    touch (2.5 mm apart or more); they are scattered: no two at the same distance from the centre
    (0.5 mm apart or more) and no three of them and the centre in line (every triangle of them at least
    1.2 mm high)."""
    offsets, (top, *chips) = object_parts(suite.family("chocolate_chip_cookie").scene.sensor.stimuli)
    assert top.kind == "punch" and np.allclose(offsets[0], 0.0)
    radii = np.array([middle(chip, "radius_mm") for chip in chips])
    reach = np.hypot(*offsets[1:].T)
    assert (reach + radii < middle(top, "radius_mm") - 8.0).all()
    for i, j in itertools.combinations(range(len(chips)), 2):
        assert np.hypot(*(offsets[1 + i] - offsets[1 + j])) > radii[i] + radii[j] + 2.5
    assert np.diff(np.sort(reach)).min() > 0.5
    for a, b, c in itertools.combinations(offsets, 3):
        (ux, uy), (vx, vy) = b - a, c - a
        longest = max(np.hypot(ux, uy), np.hypot(vx, vy), np.hypot(*(c - b)))
        assert abs(ux * vy - uy * vx) / longest > 1.2


def test_the_starfishs_arms_are_paired_ridges_round_its_mouth(suite: Suite) -> None:
    """Turned by 72 degrees about the disc's centre the ten ridges land on one another (within 0.01 mm):
    five arms. At nominal sizes the two ridges of an arm run along it either side of its groove, 1.6 mm
    wide, their inner ends at the disc's rim (within 0.05 mm along the arm), and each presses less
    towards the arm's tip (its slope falls along its angle, which points out from the centre)."""
    offsets, (mouth, *ridges) = object_parts(suite.family("dried_starfish").scene.sensor.stimuli)
    assert mouth.kind == "ring" and np.allclose(offsets[0], 0.0)
    turn = np.deg2rad(72.0)
    turned = offsets[1:] @ np.array([[np.cos(turn), np.sin(turn)], [-np.sin(turn), np.cos(turn)]])
    assert np.abs(turned[:, None] - offsets[None, 1:]).max(axis=-1).min(axis=1).max() < 0.01
    for offset, ridge in zip(offsets[1:], ridges, strict=True):
        along = direction(middle(ridge, "angle_deg"))
        assert ridge.tilt[1] < 0 and along @ offset > 0
        groove = 2 * (abs(perpendicular(middle(ridge, "angle_deg")) @ offset) - middle(ridge, "width_mm") / 2)
        assert groove == pytest.approx(1.6, abs=0.01)
        assert along @ offset - middle(ridge, "length_mm") / 2 == pytest.approx(middle(mouth, "radius_mm"), abs=0.05)


def test_the_bobbins_flanges_hold_its_thread_on_one_axis(suite: Suite) -> None:
    """At nominal sizes the three parts lie along one axis; the flanges' inner faces meet the thread's
    ends (within 0.1 mm) and their outer faces lie 11.7 mm apart, the bobbin's width; the thread is wound
    to 0.3-0.8 mm below the flanges' rims."""
    offsets, (thread, *flanges) = object_parts(suite.family("sewing_machine_bobbin").scene.sensor.stimuli)
    assert np.allclose(offsets[:, 1], 0.0) and offsets[0, 0] == 0.0
    assert all(middle(part, "angle_deg") % 180 == 0 for part in (thread, *flanges))
    for offset, flange in zip(offsets[1:], flanges, strict=True):
        inner, outer = (abs(offset[0]) + side * middle(flange, "length_mm") / 2 for side in (-1, 1))
        assert abs(inner - middle(thread, "length_mm") / 2) < 0.1 and outer == pytest.approx(11.7 / 2, abs=0.01)
        assert 0.3 < middle(flange, "radius_mm") - middle(thread, "radius_mm") < 0.8


def test_the_tracks_lands_end_at_its_face_with_the_peg_beyond(suite: Suite) -> None:
    """At nominal sizes the three lands run along the track, as long as one another, their ends flush at
    the track's end face; the grooves between them are 6 mm wide and the track 40 mm wide over them
    (within 0.01 mm); the neck runs on the middle line from the end face to the knob's rim (within
    0.05 mm)."""
    offsets, (*lands, neck, knob) = object_parts(suite.family("wooden_train_track_end").scene.sensor.stimuli)
    assert all(land.angle_deg == (90.0, 90.0) and land.length_mm == lands[0].length_mm for land in lands)
    face = offsets[0, 1] + middle(lands[0], "length_mm") / 2
    assert np.allclose(offsets[:3, 1] + middle(lands[0], "length_mm") / 2, face)
    edges = sorted(
        x + s * middle(land, "width_mm") / 2 for (x, _), land in zip(offsets[:3], lands, strict=True) for s in (-1, 1)
    )
    assert np.allclose(np.diff(edges)[1::2], 6.0, atol=0.01) and edges[-1] - edges[0] == pytest.approx(40.0, abs=0.01)
    root, tip = ends(offsets[3], neck)
    assert knob.kind == "ring" and knob.hole_fraction == (0.0, 0.0) and offsets[3, 0] == offsets[4, 0] == 0.0
    assert abs(root[1] - face) < 0.05 and abs(offsets[4, 1] - middle(knob, "radius_mm") - tip[1]) < 0.05


def test_the_leeks_layers_nest_each_touching_the_one_outside_it(suite: Suite) -> None:
    """At nominal sizes every layer lies inside the one outside it and touches it on one side (its
    centre's offset plus its radius is the outer layer's hole, within 0.05 mm), leaving a 0.6 mm gap on
    the other; the centres lie on one line, each 0.3 mm further along it, the same way; the walls are
    1.3-1.5 mm thick."""
    offsets, layers = object_parts(suite.family("leek_slice_rings").scene.sensor.stimuli)
    assert np.allclose(offsets[:, 0], 0.0) and np.allclose(np.diff(offsets[:, 1]), 0.3)
    radii = np.array([middle(layer, "radius_mm") for layer in layers])
    holes = radii * np.array([middle(layer, "hole_fraction") for layer in layers])
    assert all(1.3 <= wall <= 1.5 for wall in radii - holes)
    shift = np.diff(offsets[:, 1])
    assert np.allclose(radii[1:] + shift, holes[:-1], atol=0.05)
    assert np.allclose(holes[:-1] - (radii[1:] - shift), 0.6, atol=0.05)


def test_the_floss_runs_between_the_tips_of_the_picks_arms(suite: Suite) -> None:
    """At nominal sizes both arms start at the handle's end (their inner ends within 0.05 mm of its
    middle), splayed 32 degrees either side of it; the floss lies square to the handle, its ends at the
    arms' tips (within 0.1 mm)."""
    offsets, (handle, *arms, floss) = object_parts(suite.family("dental_floss_pick").scene.sensor.stimuli)
    assert handle.angle_deg == (90.0, 90.0) and floss.angle_deg == (0.0, 0.0) and floss.kind == "edge"
    handle_end = ends(offsets[0], handle)[1]
    tips = []
    for offset, arm in zip(offsets[1:3], arms, strict=True):
        root, tip = sorted(ends(offset, arm), key=lambda p: float(p[1]))
        assert np.hypot(*(root - handle_end)) < 0.05
        assert abs(middle(arm, "angle_deg") - 90.0) == pytest.approx(32.0)
        tips.append(tip)
    assert np.abs(np.sort(ends(offsets[3], floss), axis=0) - np.sort(tips, axis=0)).max() < 0.1


def test_the_raviolis_border_is_a_closed_frame_round_its_filling(suite: Suite) -> None:
    """At nominal sizes the four strips, equally wide, abut at the frame's corners (no overlap, no gap
    over 0.05 mm) as a square 38 mm on a side; the filling's field lies in the middle of the frame's
    opening, its lumps' centres at least 6 mm inside it."""
    offsets, (filling, *strips) = object_parts(suite.family("ravioli_parcel").scene.sensor.stimuli)
    assert filling.kind == "blob" and np.allclose(offsets[0], 0.0)
    assert all(strip.width_mm == strips[0].width_mm for strip in strips)
    across, sides = [], []
    for (x, y), strip in zip(offsets[1:], strips, strict=True):
        along, half = middle(strip, "length_mm") / 2, middle(strip, "width_mm") / 2
        if strip.angle_deg == (0.0, 0.0):
            across.append((x - along, x + along, y - half, y + half))
        else:
            assert strip.angle_deg == (90.0, 90.0)
            sides.append((x - half, x + half, y - along, y + along))
    assert len(across) == len(sides) == 2
    boxes = np.array(across + sides)
    assert np.allclose(
        [boxes[:, 0].min(), boxes[:, 1].max(), boxes[:, 2].min(), boxes[:, 3].max()], 19.0 * np.array([-1, 1, -1, 1])
    )
    bottom, top = sorted(across, key=lambda box: box[2])
    for side in sides:
        assert abs(side[2] - bottom[3]) < 0.05 and abs(side[3] - top[2]) < 0.05
    opening = min(side[0] for side in sides if side[0] > 0)
    assert opening == pytest.approx(top[2]) and middle(filling, "radius_mm") < opening - 6.0


def test_the_cones_radius_grows_along_its_line_from_its_tip(suite: Suite) -> None:
    """At nominal sizes the six pieces join end to end (within 0.05 mm) on one line from the cone's tip to
    its rim, 48 mm; each piece's tip radius is its middle's distance from the tip times the tangent of
    the cone's half-angle, 13 / sqrt(48^2 - 13^2) for a rim 13 mm in radius (within 1 %); the rim's lip
    lies square across the line's end."""
    offsets, (*pieces, lip) = object_parts(suite.family("ice_cream_cone_on_its_side").scene.sensor.stimuli)
    assert np.allclose(offsets[:, 0], 0.0) and all(piece.angle_deg == (90.0, 90.0) for piece in pieces)
    tip, corner = ends(offsets[0], pieces[0])
    for offset, piece in zip(offsets[1:-1], pieces[1:], strict=True):
        start, end = ends(offset, piece)
        assert np.hypot(*(start - corner)) < 0.05
        corner = end
    assert corner[1] - tip[1] == pytest.approx(CONE_SLANT_MM, abs=0.05)
    slope = CONE_RIM_MM / np.sqrt(CONE_SLANT_MM**2 - CONE_RIM_MM**2)
    for offset, piece in zip(offsets[:-1], pieces, strict=True):
        assert middle(piece, "radius_mm") == pytest.approx(slope * (offset[1] - tip[1]), rel=0.01)
    assert lip.kind == "edge" and lip.angle_deg == (0.0, 0.0) and np.allclose(offsets[-1], corner, atol=0.05)


def test_the_cookie_predicate_sees_the_chips_scattered(suite: Suite) -> None:
    """The same chips evenly round a circle of 12 mm radius (a decorated biscuit's, not a baked
    cookie's) are another object: the cookie's predicate rejects every frame of it."""
    fam = suite.family("chocolate_chip_cookie")
    angles = np.deg2rad(np.arange(7) * 360.0 / 7)
    ring = [(0.0, 0.0), *zip(12.0 * np.cos(angles), 12.0 * np.sin(angles), strict=True)]
    assert_told_apart(fam.scene.sensor.stimuli, moved(fam, ring))


def test_the_plait_predicate_tells_it_from_a_twist(suite: Suite) -> None:
    """The same lobes all on the middle line (a two-strand twist, whose strands cross in its middle)
    are another hairstyle: the plait's predicate rejects every frame of it."""
    fam = suite.family("three_strand_plait")
    offsets, _ = object_parts(fam.scene.sensor.stimuli)
    twist = [(float(x), 0.0) for x, _ in offsets]
    assert_told_apart(fam.scene.sensor.stimuli, moved(fam, twist))


def test_the_floss_pick_predicate_sees_the_splayed_arms(suite: Suite) -> None:
    """The same arms parallel to the handle, 10.6 mm apart with the floss across their tips (a flosser
    with a U-shaped head), are another pick: the floss pick's predicate rejects every frame of it."""
    fam = suite.family("dental_floss_pick")
    stimuli = fam.scene.sensor.stimuli
    offsets, (handle, *arms, floss) = object_parts(stimuli)
    root = ends(offsets[0], handle)[1]
    reach = middle(arms[0], "length_mm")
    u_head = [tuple(offsets[0]), (5.3, root[1] + reach / 2), (-5.3, root[1] + reach / 2), (0.0, root[1] + reach)]
    upright = tuple(dataclasses.replace(arm, angle_deg=(90.0, 90.0)) for arm in arms)
    assert_told_apart(stimuli, moved(fam, u_head, kinds=(handle, *upright, floss)))


@pytest.mark.parametrize("reference", sorted(references()))
def test_no_reference_draws_a_frame_of_any_family(suite: Suite, reference: str) -> None:
    assert_no_frame_drawn(suite, reference, references()[reference], looks_like)


def test_every_family_but_the_single_contacts_is_an_object(suite: Suite) -> None:
    """No family here is a single contact: every family places its contacts as the parts of one object
    (the arrangement the predicates check)."""
    assert_objects_but_the_single_contacts(suite, set())
