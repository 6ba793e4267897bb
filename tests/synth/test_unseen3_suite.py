"""The strips16_unseen3 suite (unseen shapes, round 3): it parses, every family generates frames
within the sensor's range, and every family lies outside everything the strip models were trained on
- the five mixed scenes and the object scenes (synth/scenes/strips16_objects_*.toml) - the OOD suite
and rounds 1 and 2, twice over:

- from the TOML files: contact counts no reference draws, a shape every frame holds that no
  reference entry of its kind draws, or contacts placed as the parts of one rigid object where the
  reference draws each centre independently (an exact arrangement then has probability zero) or
  places another object (no count both draw gives similar point sets);
- in drawn frames: a predicate that recognises a family's frames (its count, every contact's kind and
  sizes, the parts' pairwise distances up to the object's scale; forces and angles ignored, which
  can only widen it) accepts every frame of the family and no frame drawn from any reference.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from functools import cache

import numpy as np
import pytest

from synth.scene import Scene, load_scene
from synth.sensors.strips.config import ContactObject, StimulusKind, StripStimuli, allowed_intervals
from synth.suite import Suite, load_suite
from tests.paths import REPO_ROOT
from tests.synth.test_objects_scenes import Contacts, draw
from tests.synth.test_unseen2_suite import TRAINING, drawable
from tests.synth.test_unseen_suite import assert_frames_within_range
from tests.synth.test_wide_scene import drawn_counts

SUITE = "strips16_unseen3"
OBJECT_SCENES = tuple(sorted(p.stem for p in (REPO_ROOT / "synth" / "scenes").glob("strips16_objects_*.toml")))
EARLIER_SUITES = ("strips16_ood", "strips16_unseen", "strips16_unseen2")
#: the sizes that tell contacts of one kind apart in drawn frames (forces and angles left out: a
#: predicate blind to them accepts more reference frames, never fewer)
SIZES = {
    "sphere": ("radius_mm",),
    "punch": ("radius_mm", "tilt"),
    "block": ("width_mm", "length_mm", "tilt"),
    "edge": ("radius_mm", "length_mm"),
    "ring": ("radius_mm", "hole_fraction"),
    "terminal": ("radius_mm", "hole_fraction", "width_mm", "length_mm"),
    "blob": ("radius_mm", "width_mm"),
}
#: how far a drawn frame's normalised pairwise distances may stray from the object's and still be it
SHAPE_TOLERANCE = 0.03


@cache
def reference_scenes() -> dict[str, Scene]:
    """Every scene a strip model trained on, and every family of the earlier suites."""
    refs = {name: load_scene(name) for name in (*TRAINING, *OBJECT_SCENES)}
    for suite in EARLIER_SUITES:
        refs.update({f"{suite}/{f.name}": f.scene for f in load_suite(suite).families})
    return refs


def signature(offsets: tuple[tuple[float, float], ...]) -> np.ndarray:
    """The parts' pairwise distances, sorted, over the largest: equal for similar point sets."""
    xy = np.asarray(offsets, dtype=np.float64)
    d = np.linalg.norm(xy[:, None] - xy[None, :], axis=-1)[np.triu_indices(len(xy), 1)]
    return np.sort(d / d.max()) if d.size and d.max() > 0 else np.zeros(d.size)


def similar_counts(family: StripStimuli, reference: StripStimuli) -> list[int]:
    """Counts both draw at which the family's object and the reference's place similar point sets."""
    assert family.object is not None and reference.object is not None
    common = (set(range(family.count[0], family.count[1] + 1)) - {0}) & drawn_counts(reference)
    return [
        k
        for k in sorted(common)
        if np.allclose(signature(family.object.offsets_mm[:k]), signature(reference.object.offsets_mm[:k]), atol=1e-3)
    ]


def in_every_frame(family: StripStimuli) -> tuple[StimulusKind, ...]:
    """The entries some contact of every frame is drawn from (with one entry, or one per part)."""
    if family.object is not None and family.object.part_kinds:
        return family.kinds[: family.count[0]]
    return family.kinds if len(family.kinds) == 1 else ()


def novelty(family: StripStimuli, reference: StripStimuli) -> list[str]:
    """Why frames of ``family`` cannot be drawn from ``reference`` (empty: they can)."""
    reasons = []
    counts = set(range(family.count[0], family.count[1] + 1)) - {0}
    if not counts & drawn_counts(reference):
        reasons.append(f"{sorted(counts)} contacts (reference: {sorted(drawn_counts(reference))})")
    reasons += [f"{s.kind} outside its ranges" for s in in_every_frame(family) if not drawable(reference, s)]
    if family.object is not None and family.count[1] >= 2:
        if reference.object is None:
            reasons.append("parts of one object")
        elif not similar_counts(family, reference):
            reasons.append("another arrangement")
    return reasons


def _inside(values: np.ndarray, spec: StimulusKind, name: str) -> np.ndarray:
    lo, hi = getattr(spec, name)
    out = np.zeros(values.shape, dtype=bool)
    for a, b in allowed_intervals(float(lo), float(hi), spec.holdouts(name)):
        out |= (values >= a - 1e-6) & (values <= b + 1e-6)
    return out


def _sized_like(c: Contacts, names: np.ndarray, spec: StimulusKind) -> np.ndarray:
    """Contacts (B, K) of ``spec``'s kind whose sizes it draws (a block's sides either way round)."""
    sizes = SIZES[spec.kind]
    ok = names == spec.kind
    for name in sizes:
        if spec.kind != "block" or name == "tilt":
            ok &= _inside(c[name], spec, name)
    if spec.kind == "block":
        w, length = c["width_mm"], c["length_mm"]
        as_drawn = _inside(w, spec, "width_mm") & _inside(length, spec, "length_mm")
        turned = _inside(length, spec, "width_mm") & _inside(w, spec, "length_mm")
        ok &= as_drawn | turned
    return ok


def looks_like(family: StripStimuli, c: Contacts, names: np.ndarray) -> np.ndarray:
    """Frames that could be one of ``family``'s: its count, every contact sized as one of its entries,
    and for an object the centres' pairwise distances those of its parts at one of its scales."""
    present = c["present"]
    count = c["count"]
    sized = np.zeros(present.shape, dtype=bool)
    for spec in family.kinds:
        sized |= _sized_like(c, names, spec)
    ok = (count >= family.count[0]) & (count <= family.count[1]) & (sized | ~present).all(axis=1)
    obj = family.object
    if obj is None:
        return ok
    xy = np.stack([c["x_mm"], c["y_mm"]], -1)
    for k in np.unique(count[ok]):
        if k < 2:
            continue
        rows = np.nonzero(ok & (count == k))[0]
        upper = np.triu_indices(k, 1)
        d = np.linalg.norm(xy[rows, :k, None] - xy[rows, None, :k], axis=-1)[:, upper[0], upper[1]]
        ref = np.asarray(obj.offsets_mm[:k], dtype=np.float64)
        d_ref = np.linalg.norm(ref[:, None] - ref[None, :], axis=-1)[upper]
        scale = d.max(axis=1) / d_ref.max()
        shape = np.abs(np.sort(d, axis=1) / d.max(axis=1, keepdims=True) - np.sort(d_ref) / d_ref.max()).max(axis=1)
        sized_right = (scale >= obj.scale[0] * 0.98) & (scale <= obj.scale[1] * 1.02)
        ok[rows] &= (shape <= SHAPE_TOLERANCE) & sized_right
    return ok


#: a family's frames among drawn contacts: (family, contacts, kind names) -> (B,) mask
Predicate = Callable[[StripStimuli, Contacts, np.ndarray], np.ndarray]


@pytest.fixture(scope="module")
def suite() -> Suite:
    return load_suite(SUITE)


def test_suite_parses_with_its_families_described(suite: Suite) -> None:
    assert suite.base.name == "strips16" and 10 <= len(suite.families) <= 14
    assert not [f.name for f in suite.families if len(f.description) <= 40]
    earlier = set().union(*(load_suite(s).names for s in EARLIER_SUITES))
    assert not set(suite.names) & earlier
    assert len(OBJECT_SCENES) >= 8  # strips-objects' scenes are here to be checked against


def assert_outside(suite: Suite, references: dict[str, Scene]) -> None:
    """Every family of ``suite`` has a reason (:func:`novelty`) against every reference."""
    refs = {name: scene.sensor.stimuli for name, scene in references.items()}
    for fam in suite.families:
        stimuli = fam.scene.sensor.stimuli
        for name, ref in refs.items():
            assert novelty(stimuli, ref), f"{fam.name}: {name} draws frames like these"


def assert_no_frame_drawn(suite: Suite, reference: str, scene: Scene, predicate: Predicate) -> None:
    """No frame of 3,000 drawn from ``scene`` is accepted by any family's ``predicate``."""
    contacts, names = draw(scene, 3000, seed=21)
    for fam in suite.families:
        hits = predicate(fam.scene.sensor.stimuli, contacts, names)
        assert not hits.any(), (fam.name, reference, int(hits.sum()))


def test_every_family_lies_outside_training_the_ood_suite_and_rounds_1_and_2(suite: Suite) -> None:
    assert_outside(suite, reference_scenes())


def test_the_novelty_check_can_fail(suite: Suite) -> None:
    """The same object on both sides is no reason; the tripod's triangle placed by a reference with
    three-part objects of another shape is; without its object the shoe sole is novel by its count
    alone, and the cup by its ring's radius, which a ring within the wide scene's ranges loses."""
    wide = load_scene("strips16_wide").sensor.stimuli
    tripod = suite.family("tripod_feet").scene.sensor.stimuli
    assert novelty(tripod, tripod) == []
    grid = load_scene("strips16_objects_grid_3x3").sensor.stimuli  # three feet: its first row
    assert novelty(tripod, grid) == ["another arrangement"]
    same_shape = dataclasses.replace(grid, count=(3, 3), count_weights=(), object=tripod.object)
    assert novelty(tripod, same_shape) == []
    sole = suite.family("shoe_sole_nubs").scene.sensor.stimuli
    assert novelty(dataclasses.replace(sole, object=None), wide) == ["[14] contacts (reference: [1, 2, 3, 4, 6])"]
    cup = suite.family("espresso_cup_foot").scene.sensor.stimuli
    assert novelty(cup, wide) == ["ring outside its ranges"]
    smaller = dataclasses.replace(cup.kinds[0], radius_mm=(12.0, 14.5), hole_fraction=(0.75, 0.85))
    assert novelty(dataclasses.replace(cup, kinds=(smaller,)), wide) == []


def test_every_family_generates_frames_within_the_sensors_range(suite: Suite) -> None:
    # well below the ADC's full scale (the strongest of 200 noise-free frames a family: 0.64 of it)
    assert_frames_within_range(suite, full_scale_share=0.8)


def assert_own_frames_accepted(suite: Suite, predicate: Predicate) -> None:
    """Each family's ``predicate`` accepts every one of 400 frames drawn from the family."""
    for fam in suite.families:
        contacts, names = draw(fam.scene, 400, seed=3)
        assert predicate(fam.scene.sensor.stimuli, contacts, names).all(), fam.name


def test_each_familys_predicate_accepts_its_own_frames(suite: Suite) -> None:
    assert_own_frames_accepted(suite, looks_like)


def test_the_predicates_can_fail() -> None:
    """A familiar object is seen: a 2 x 2 square of feet is drawn by the square-grid scene, three
    feet in a row by the 3 x 3 grid's first row; the same square turned into a rectangle is not."""
    grid = load_scene("strips16_objects_grid_square")
    contacts, names = draw(grid, 2000, seed=4)
    feet = (StimulusKind("punch", radius_mm=(0.85, 6.0)), StimulusKind("sphere", radius_mm=(1.5, 8.8)))
    square = StripStimuli(
        count=(4, 4),
        kinds=feet,
        object=ContactObject(offsets_mm=((-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)), scale=(2.0, 7.0)),
    )
    assert looks_like(square, contacts, names).mean() > 0.1
    rectangle = dataclasses.replace(
        square, object=ContactObject(offsets_mm=((-1.5, -1.0), (1.5, -1.0), (-1.5, 1.0), (1.5, 1.0)), scale=(1.0, 7.0))
    )
    assert not looks_like(rectangle, contacts, names).any()
    contacts, names = draw(load_scene("strips16_objects_grid_3x3"), 2000, seed=4)
    in_a_row = ContactObject(offsets_mm=((-1.0, 0.0), (0.0, 0.0), (1.0, 0.0)), scale=(3.0, 7.4))
    row = dataclasses.replace(square, count=(3, 3), object=in_a_row)
    assert looks_like(row, contacts, names).mean() > 0.05


@pytest.mark.parametrize("reference", sorted(reference_scenes()))
def test_no_reference_draws_a_frame_of_any_family(suite: Suite, reference: str) -> None:
    assert_no_frame_drawn(suite, reference, reference_scenes()[reference], looks_like)
