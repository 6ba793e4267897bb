"""The strips16_unseen7 suite (unseen shapes, round 7): it parses, every family generates frames
within the sensor's range, and every family lies outside every strip scene in synth/scenes/, the OOD
suite and rounds 1-6, checked as rounds 4-6 check themselves: from the TOML files (counts, shapes,
arrangements) and in drawn frames (a predicate per family accepts its own frames and no frame of any
reference).

Written blind, before any model was evaluated on the suite: what this round can say is that no
*object* here is one a scene or an earlier round draws.
"""

from __future__ import annotations

import dataclasses
from functools import cache

import pytest

from synth.scene import Scene, load_scene
from synth.sensors.strips.config import ContactObject, StripStimuli
from synth.suite import Family, Suite, load_suite
from tests.synth.test_objects_scenes import draw
from tests.synth.test_unseen3_suite import EARLIER_SUITES, assert_no_frame_drawn, assert_outside, novelty
from tests.synth.test_unseen3_suite import assert_own_frames_accepted as assert_own_frames_accepted_by
from tests.synth.test_unseen4_suite import looks_like
from tests.synth.test_unseen5_suite import STRIP_SCENES, assert_objects_but_the_single_contacts
from tests.synth.test_unseen6_suite import references as round6_references
from tests.synth.test_unseen_suite import assert_frames_within_range

SUITE = "strips16_unseen7"
ROUND_6 = "strips16_unseen6"


def rounds_through(last: int) -> tuple[str, ...]:
    """The OOD suite and the unseen rounds 1..``last``: the suites a later round must lie outside."""
    return (*EARLIER_SUITES, *(f"strips16_unseen{k}" for k in range(3, last + 1)))


def references_with(previous: dict[str, Scene], round_suite: str) -> dict[str, Scene]:
    """``previous`` references, the families of ``round_suite``, and any strip scene added since."""
    refs = {**previous, **{f"{round_suite}/{f.name}": f.scene for f in load_suite(round_suite).families}}
    refs.update({name: load_scene(name) for name in STRIP_SCENES if name not in refs})
    return refs


def assert_round_parses(suite: Suite, earlier_rounds: tuple[str, ...], refs: dict[str, Scene], earlier: int) -> None:
    """A round of 12 described families at 600 frames, named unlike any of ``earlier_rounds`` (which hold
    ``earlier`` families), its references every strip scene and every earlier family."""
    assert suite.base.name == "strips16" and len(suite.families) == 12 and suite.frames == 600
    assert not [f.name for f in suite.families if len(f.description) <= 40]
    assert not set(suite.names) & set().union(*(load_suite(s).names for s in earlier_rounds))
    assert set(STRIP_SCENES) <= set(refs) and len(STRIP_SCENES) >= 20
    families = sum(len(load_suite(s).families) for s in earlier_rounds)
    assert families == earlier
    assert len(refs) == len(STRIP_SCENES) + families


EARLIER_ROUNDS = rounds_through(6)
#: braille's six dots of a cell (1-3 down the left column, 4-6 down the right), 2.5 mm apart
BRAILLE_DOTS = {1: (0.0, 0.0), 2: (0.0, -2.5), 3: (0.0, -5.0), 4: (2.5, 0.0), 5: (2.5, -2.5), 6: (2.5, -5.0)}
#: a braille cell's pitch along a line (mm)
BRAILLE_CELL_MM = 6.2


@cache
def references() -> dict[str, Scene]:
    """Round 6's references (every strip scene, the OOD suite, rounds 1-5), round 6's families, and any
    strip scene added since."""
    return references_with(round6_references(), ROUND_6)


def braille(word: tuple[tuple[int, ...], ...]) -> tuple[tuple[float, float], ...]:
    """The dots of ``word`` (each letter its dot numbers), centred on their bounding box (mm)."""
    dots = [
        (c * BRAILLE_CELL_MM + BRAILLE_DOTS[d][0], BRAILLE_DOTS[d][1]) for c, letter in enumerate(word) for d in letter
    ]
    xs, ys = [x for x, _ in dots], [y for _, y in dots]
    cx, cy = (max(xs) + min(xs)) / 2, (max(ys) + min(ys)) / 2
    return tuple((round(x - cx, 4), round(y - cy, 4)) for x, y in dots)


#: e (1, 5), x (1, 3, 4, 6), i (2, 4), t (2, 3, 4, 5): the sign's word
EXIT = ((1, 5), (1, 3, 4, 6), (2, 4), (2, 3, 4, 5))
#: l (1, 2, 3), i (2, 4), f (1, 2, 4), t (2, 3, 4, 5): another word of twelve dots
LIFT = ((1, 2, 3), (2, 4), (1, 2, 4), (2, 3, 4, 5))


def with_stimuli(fam: Family, **changes: object) -> Scene:
    """The family's scene with some of its stimuli's fields replaced."""
    stimuli = dataclasses.replace(fam.scene.sensor.stimuli, **changes)
    return dataclasses.replace(fam.scene, sensor=dataclasses.replace(fam.scene.sensor, stimuli=stimuli))


def assert_told_apart(stimuli: StripStimuli, other: Scene) -> None:
    """``other`` (a family's scene changed in one respect) is another object: the family's predicate
    (``stimuli``) rejects every one of 500 frames of it, and ``other``'s own accepts them all."""
    contacts, names = draw(other, 500, seed=4)
    assert not looks_like(stimuli, contacts, names).any()
    assert looks_like(other.sensor.stimuli, contacts, names).all()


@pytest.fixture(scope="module")
def suite() -> Suite:
    return load_suite(SUITE)


def test_suite_parses_with_its_families_described(suite: Suite) -> None:
    assert_round_parses(suite, EARLIER_ROUNDS, references(), 11 + 13 + 12 + 12 + 12 + 12 + 12)


def test_the_braille_sign_spells_exit(suite: Suite) -> None:
    stimuli = suite.family("braille_exit_sign").scene.sensor.stimuli
    assert stimuli.object is not None and stimuli.object.offsets_mm == braille(EXIT)


def test_every_family_lies_outside_every_strip_scene_the_ood_suite_and_rounds_1_to_6(suite: Suite) -> None:
    assert_outside(suite, references())


def test_the_novelty_check_can_fail(suite: Suite) -> None:
    """The same object on both sides is no reason; the coin on its rim is new to the wide scene by its
    radius and length, and an edge within the wide scene's ranges is not; the keyboard is new to the
    wide scene by its arrangement alone (its keys placed independently are pads the wide scene draws);
    the spanner is new to round 4's house key by its ring's radius, which a ring of the key's size
    loses."""
    wide = load_scene("strips16_wide").sensor.stimuli
    coin = suite.family("coin_on_edge").scene.sensor.stimuli
    assert novelty(coin, coin) == []
    assert novelty(coin, wide) == ["edge outside its ranges"]
    short = dataclasses.replace(coin.kinds[0], radius_mm=(2.0, 3.0), length_mm=(3.0, 6.0))
    assert novelty(dataclasses.replace(coin, kinds=(short,)), wide) == []
    keys = suite.family("keyboard_keys").scene.sensor.stimuli
    assert novelty(keys, wide) == ["parts of one object"]
    assert novelty(dataclasses.replace(keys, object=None), wide) == []
    key = load_suite("strips16_unseen4").family("house_key_flat").scene.sensor.stimuli
    spanner = suite.family("spanner_ring_end").scene.sensor.stimuli
    assert novelty(spanner, key) == ["terminal outside its ranges"]
    bow = dataclasses.replace(spanner.kinds[0], radius_mm=(11.0, 12.0), hole_fraction=(0.12, 0.18), width_mm=(7.0, 8.0))
    assert novelty(dataclasses.replace(spanner, kinds=(bow,)), key) == []


def test_every_family_generates_frames_within_the_sensors_range(suite: Suite) -> None:
    # well below the ADC's full scale (the strongest of the six frames a family: the coin, 0.31 of it)
    assert_frames_within_range(suite, full_scale_share=0.5)


def test_each_familys_predicate_accepts_its_own_frames(suite: Suite) -> None:
    assert_own_frames_accepted_by(suite, looks_like)


def test_a_circles_predicate_tells_the_shower_head_from_a_square_grid(suite: Suite) -> None:
    """The same sixteen nozzles on a 4 x 4 square grid (a hairbrush's arrangement, 5-6 mm pitch at the
    shower head's scales) are another object: the shower head's predicate rejects every frame of it."""
    fam = suite.family("shower_head_nozzles")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    grid = dataclasses.replace(
        stimuli.object, offsets_mm=tuple((x, y) for y in (-1.2, -0.4, 0.4, 1.2) for x in (-1.2, -0.4, 0.4, 1.2))
    )
    gridded = with_stimuli(fam, object=grid)
    assert_told_apart(stimuli, gridded)


def test_the_braille_predicate_reads_the_word(suite: Suite) -> None:
    """The same twelve dots spelling 'lift' are another sign: the predicate for 'exit' rejects every
    frame of it, and the predicate for 'lift' accepts them all."""
    fam = suite.family("braille_exit_sign")
    stimuli = fam.scene.sensor.stimuli
    assert stimuli.object is not None
    lift: ContactObject = dataclasses.replace(stimuli.object, offsets_mm=braille(LIFT))
    other = with_stimuli(fam, object=lift)
    assert_told_apart(stimuli, other)


def test_the_chain_predicate_counts_its_flat_and_upright_links(suite: Suite) -> None:
    """Nine flat links in the chain's row (every link a ring of the chain's) pass the sizes and the
    arrangement but not the kinds' count: the chain's predicate rejects every frame of them."""
    fam = suite.family("belcher_chain")
    stimuli = fam.scene.sensor.stimuli
    flattened = with_stimuli(fam, kinds=(stimuli.kinds[0],) * 9)
    assert_told_apart(stimuli, flattened)


@pytest.mark.parametrize("reference", sorted(references()))
def test_no_reference_draws_a_frame_of_any_family(suite: Suite, reference: str) -> None:
    assert_no_frame_drawn(suite, reference, references()[reference], looks_like)


def test_every_family_but_the_single_contacts_is_an_object(suite: Suite) -> None:
    """The families of one contact are new by their shape alone; every other family places its
    contacts as the parts of one object (the arrangement the predicates check)."""
    assert_objects_but_the_single_contacts(
        suite, {"spanner_ring_end", "coin_on_edge", "screwdriver_tip", "water_balloon"}
    )
