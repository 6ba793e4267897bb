"""The strips16_unseen2 suite (unseen shapes, round 2): it parses, every family generates frames
within the sensor's range, and every family lies outside everything the strip models were trained
on (the five training scenes), the OOD suite and round 1 (strips16_unseen), asserted from the TOML
files: contact counts no reference draws, a shaping parameter no reference entry of that kind
draws, or contacts placed as the parts of one rigid object where every reference draws each centre
independently (an exact arrangement - studs on their pitch, centres on one strip, parallel tines -
then has probability zero). The drawn frames are checked to have the arrangement they claim."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from synth.scene import load_scene
from synth.sensors.strips.config import ContactObject, StimulusKind, StripStimuli
from synth.sensors.strips.stimuli import ContactGenerator
from synth.suite import Suite, load_suite
from tests.synth.test_unseen_suite import SHAPING, assert_frames_within_range
from tests.synth.test_wide_scene import _allowed, _overlap, drawn_counts

TRAINING = ("strips16_wide", "strips16_mixed", "strips16_mixed_smooth", "strips16_mixed_single", "strips16")
SUITE = "strips16_unseen2"
#: a punch's tilt shapes it too (a moment: synth.stimuli)
SHAPES = {**SHAPING, "punch": (*SHAPING["punch"], "tilt")}


def references() -> dict[str, StripStimuli]:
    refs = {name: load_scene(name).sensor.stimuli for name in TRAINING}
    for suite in ("strips16_ood", "strips16_unseen"):
        refs.update({f"{suite}/{f.name}": f.scene.sensor.stimuli for f in load_suite(suite).families})
    return refs


def drawable(reference: StripStimuli, shape: StimulusKind) -> bool:
    """Some entry of ``reference`` draws ``shape``'s kind within all of its shaping ranges."""
    return any(
        spec.kind == shape.kind and all(_overlap(_allowed(spec, p), _allowed(shape, p)) for p in SHAPES[shape.kind])
        for spec in reference.kinds
    )


def novelty(family: StripStimuli, reference: StripStimuli) -> list[str]:
    """Why frames of ``family`` cannot be drawn from ``reference`` (empty: they can)."""
    reasons = []
    counts = set(range(family.count[0], family.count[1] + 1)) - {0}
    if not counts & drawn_counts(reference):
        reasons.append(f"{sorted(counts)} contacts (reference: {sorted(drawn_counts(reference))})")
    if family.object is not None and family.count[1] >= 2 and reference.object != family.object:
        reasons.append("parts of one object" if reference.object is None else "another object")
    reasons += [f"{s.kind} outside its ranges" for s in family.kinds if not drawable(reference, s)]
    return reasons


@pytest.fixture(scope="module")
def suite() -> Suite:
    return load_suite(SUITE)


def test_suite_parses_with_its_families_described(suite: Suite) -> None:
    assert suite.base.name == "strips16"
    assert 10 <= len(suite.families) <= 14
    for fam in suite.families:
        assert len(fam.description) > 40, fam.name
    round1 = set(load_suite("strips16_unseen").names) | set(load_suite("strips16_ood").names)
    assert not set(suite.names) & round1


def test_every_family_lies_outside_training_the_ood_suite_and_round_1(suite: Suite) -> None:
    refs = references()
    assert all(ref.object is None for ref in refs.values())  # nothing drawn before places objects
    for fam in suite.families:
        stimuli = fam.scene.sensor.stimuli
        for name, ref in refs.items():
            assert novelty(stimuli, ref), f"{fam.name}: {name} draws frames like these"


def test_the_novelty_check_can_fail(suite: Suite) -> None:
    """Without its object, two chopsticks are two edges the wide scene draws; without its tilt, the
    coin is a punch it draws; eight studs are novel by their count alone; and the same object on both
    sides is no reason."""
    wide = load_scene("strips16_wide").sensor.stimuli
    chopsticks = suite.family("chopsticks").scene.sensor.stimuli
    assert novelty(chopsticks, wide) == ["parts of one object"]
    assert novelty(dataclasses.replace(chopsticks, object=None), wide) == []
    coin = suite.family("coin_off_centre").scene.sensor.stimuli
    assert novelty(coin, wide) == ["punch outside its ranges"]
    untilted = dataclasses.replace(coin.kinds[0], tilt=(0.0, 0.0))
    assert novelty(dataclasses.replace(coin, kinds=(untilted,)), wide) == []
    studs = suite.family("lego_2x4").scene.sensor.stimuli
    assert novelty(dataclasses.replace(studs, object=None), wide) == ["[8] contacts (reference: [1, 2, 3, 4, 6])"]
    assert novelty(chopsticks, chopsticks) == []


def test_every_family_generates_frames_within_the_sensors_range(suite: Suite) -> None:
    # well below the ADC's full scale (the strongest of 200 noise-free frames a family: 0.53 of it)
    assert_frames_within_range(suite, full_scale_share=0.8)


def _direction_deg(obj: ContactObject, xy: np.ndarray) -> np.ndarray:
    """How far each frame's object is turned: the first two parts' direction against their offsets'."""
    (x0, y0), (x1, y1) = obj.offsets_mm[:2]
    v = xy[:, 1] - xy[:, 0]
    return np.mod(np.rad2deg(np.arctan2(v[:, 1], v[:, 0]) - np.arctan2(y1 - y0, x1 - x0)), 360.0)


def test_drawn_frames_have_the_arrangement_each_family_names(suite: Suite) -> None:
    """Rigid: every frame's pairwise distances are the offsets' times one scale; aligned families
    lie along their strip; the cross's and the L's bars are square to each other; tines and sticks
    are parallel and side by side."""
    rng = np.random.default_rng(12)
    for fam in suite.families:
        stimuli = fam.scene.sensor.stimuli
        obj = stimuli.object
        if obj is None:
            continue
        c = ContactGenerator(fam.scene.sensor, rasterize=False).draw_contacts(300, rng)
        xy = np.stack([c["x_mm"], c["y_mm"]], -1)
        ref = np.asarray(obj.offsets_mm, dtype=np.float64)
        d = np.linalg.norm(xy[:, :, None] - xy[:, None, :], axis=-1)
        d_ref = np.linalg.norm(ref[:, None] - ref[None, :], axis=-1)
        if d_ref.max() > 0:
            i, j = np.unravel_index(np.argmax(d_ref), d_ref.shape)
            scale = d[:, i, j] / d_ref[i, j]
            assert np.allclose(d, scale[:, None, None] * d_ref, atol=1e-9), fam.name
            assert (scale >= obj.scale[0] - 1e-9).all() and (scale <= obj.scale[1] + 1e-9).all(), fam.name
        margin = stimuli.margin_mm
        assert xy.min() >= margin - 1e-9 and xy.max() <= 40.0 - margin + 1e-9, fam.name
    along_row = ContactGenerator(suite.family("fingertips_along_row").scene.sensor, rasterize=False)
    c = along_row.draw_contacts(300, rng)
    assert (np.ptp(c["y_mm"], axis=1) <= 2 * 18.0 * np.sin(np.deg2rad(3.0)) + 1e-9).all()  # within 3 degrees
    pinch = suite.family("pinch_along_column").scene
    c = ContactGenerator(pinch.sensor, rasterize=False).draw_contacts(300, rng)
    assert (np.abs(np.diff(c["x_mm"], axis=1)) <= 30.0 * np.sin(np.deg2rad(3.0)) + 1e-9).all()
    assert (c["radius_mm"][:, 0] >= 9.0).all() and (c["radius_mm"][:, 1] <= 8.0).all()  # thumb, then finger
    for name in ("cross_bracket", "angle_bracket"):
        c = ContactGenerator(suite.family(name).scene.sensor, rasterize=False).draw_contacts(300, rng)
        assert np.allclose(np.cos(np.deg2rad(c["angle_deg"][:, 1] - c["angle_deg"][:, 0])), 0.0, atol=1e-9), name
    for name in ("fork_tines", "chopsticks"):
        scene = suite.family(name).scene
        c = ContactGenerator(scene.sensor, rasterize=False).draw_contacts(300, rng)
        angle = np.deg2rad(c["angle_deg"])
        assert np.allclose(np.sin(angle - angle[:, :1]), 0.0, atol=1e-9), name  # parallel
        # side by side: the step between neighbours is square to the bars' direction
        step = np.diff(np.stack([c["x_mm"], c["y_mm"]], -1), axis=1)
        along = step[..., 0] * np.cos(angle[:, 1:]) + step[..., 1] * np.sin(angle[:, 1:])
        assert np.allclose(along, 0.0, atol=1e-9), name
        assert np.ptp(_direction_deg(scene.sensor.stimuli.object, np.stack([c["x_mm"], c["y_mm"]], -1))) > 150
