"""The strips16_unseen suite: it parses, every family generates physical frames, and every family
is unlike both the training scene (strips16_mixed) and every family of the OOD suite, asserted from
the parsed TOML files: a parameter range that no reference entry of the same kind can draw, a kind
the reference lacks, or more contacts per frame than the reference has."""

from __future__ import annotations

import numpy as np

from synth.scene import load_scene
from synth.sensors.strips.config import Holdout, StimulusKind, StripStimuli, allowed_intervals
from synth.suite import Suite, load_suite, suite_frames

#: the drawn parameters that shape each kind (synth.stimuli's docstring); the others are ignored
#: by the rasteriser, so a family cannot be novel through them
SHAPING = {
    "sphere": ("force_n", "radius_mm"),
    "punch": ("force_n", "radius_mm"),
    "block": ("force_n", "width_mm", "length_mm", "angle_deg", "tilt"),
    "edge": ("force_n", "radius_mm", "length_mm", "angle_deg"),
    "ring": ("force_n", "radius_mm", "hole_fraction"),
    "terminal": ("force_n", "radius_mm", "hole_fraction", "width_mm", "length_mm", "angle_deg"),
    "blob": ("force_n", "radius_mm", "width_mm"),
}


def _pieces(spec: StimulusKind, name: str) -> list[tuple[float, float]]:
    """The values of ``name`` that ``spec`` draws: its range minus its holdouts."""
    lo, hi = getattr(spec, name)
    return allowed_intervals(float(lo), float(hi), spec.holdouts(name))


def _overlaps(spec: StimulusKind, reference: StimulusKind, name: str) -> bool:
    """Can ``reference`` draw a value of ``name`` that ``spec`` draws?"""
    return any(max(a, c) <= min(b, d) for a, b in _pieces(spec, name) for c, d in _pieces(reference, name))


def novelty(family: StripStimuli, reference: StripStimuli) -> list[str]:
    """Why frames of ``family`` cannot be drawn from ``reference`` (empty: they can)."""
    reasons = []
    if family.count[1] > reference.count[1]:
        reasons.append(f"{family.count[1]} contacts (reference: at most {reference.count[1]})")
    for spec in family.kinds:
        same = [r for r in reference.kinds if r.kind == spec.kind]
        if not same:
            reasons.append(f"kind {spec.kind} (not in the reference)")
            continue
        misses = []
        for ref in same:
            missed = [p for p in SHAPING[spec.kind] if not _overlaps(spec, ref, p)]
            if not missed:
                return reasons  # this kind's contacts can be drawn from ``ref``
            misses.append(missed)
        reasons.append(f"{spec.kind}: " + "; ".join(",".join(m) for m in misses))
    return reasons


def test_suite_parses_with_its_families_described() -> None:
    suite = load_suite("strips16_unseen")
    assert suite.base.name == "strips16"
    assert 10 <= len(suite.families) <= 14
    for fam in suite.families:
        assert len(fam.description) > 20, fam.name


def test_every_family_is_unlike_training_and_the_ood_suite() -> None:
    training = load_scene("strips16_mixed").sensor.stimuli
    ood = load_suite("strips16_ood")
    for fam in load_suite("strips16_unseen").families:
        stimuli = fam.scene.sensor.stimuli
        assert novelty(stimuli, training), f"{fam.name}: training (strips16_mixed) draws frames like these"
        for other in ood.families:
            assert novelty(stimuli, other.scene.sensor.stimuli), f"{fam.name}: like strips16_ood/{other.name}"


def test_the_novelty_check_sees_a_familiar_family() -> None:
    """The check is not vacuous: a family inside the training ranges has no reason to be novel, and
    moving one parameter or the count past the range gives one."""
    training = load_scene("strips16_mixed").sensor.stimuli
    inside = StripStimuli(count=(2, 2), kinds=(StimulusKind("sphere", force_n=(1.0, 6.0), radius_mm=(3.0, 8.0)),))
    assert novelty(inside, training) == []
    large = StripStimuli(count=(1, 1), kinds=(StimulusKind("punch", force_n=(1.0, 6.0), radius_mm=(6.5, 9.0)),))
    assert novelty(large, training) == ["punch: radius_mm"]
    crowded = StripStimuli(count=(5, 5), kinds=inside.kinds)
    assert novelty(crowded, training) == ["5 contacts (reference: at most 4)"]
    # a block at 30 degrees is held out of training's flat blocks, but the tilted blocks draw it
    block = StimulusKind("block", force_n=(1.0, 6.0), width_mm=(4.0, 6.0), length_mm=(10.0, 12.0), angle_deg=(30, 30))
    assert novelty(StripStimuli(count=(1, 1), kinds=(block,)), training) == []

    # a family's own holdouts count: only steep tilts, at lengths the tilted blocks skip
    def steep(holdout: tuple[Holdout, ...] = ()) -> StripStimuli:
        kind = StimulusKind(
            "block", force_n=(1.0, 6.0), width_mm=(8.0, 10.0), length_mm=(14.0, 16.0), tilt=(-1.0, 1.0), holdout=holdout
        )
        return StripStimuli(count=(1, 1), kinds=(kind,))

    assert novelty(steep(), training) == []
    tilted = steep((Holdout("tilt", -0.7, 0.7),))
    assert novelty(tilted, training) == ["block: tilt; length_mm"]


def test_every_family_generates_frames_within_the_sensors_range() -> None:
    assert_frames_within_range(load_suite("strips16_unseen"))


def assert_frames_within_range(suite: Suite, full_scale_share: float = 1.0) -> None:
    """Six frames a family: finite, pressed, within the family's counts, below ``full_scale_share``
    of the ADC's full scale."""
    frames = suite_frames(suite, 6, seed=11)
    for fam in suite.families:
        arrays = frames[fam.name]
        readout = fam.scene.sensor.readout
        readings, pressure = arrays["readings"], arrays["pressure"]
        assert readings.shape == (6, 32) and pressure.shape == (6, 16, 16), fam.name
        assert np.isfinite(readings).all() and (pressure >= 0).all(), fam.name
        # every frame is pressed (no family draws empty frames) and none clips the ADC
        assert (pressure.reshape(6, -1).sum(axis=1) > 0).all(), fam.name
        assert readings.max() < full_scale_share * readout.full_scale_v, fam.name
        count = fam.scene.sensor.stimuli.count
        assert ((arrays["latent_n_contacts"] >= count[0]) & (arrays["latent_n_contacts"] <= count[1])).all()
