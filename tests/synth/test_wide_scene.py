"""The widened training scene of the strip array (synth/scenes/strips16_wide.toml): it parses as the
strips16_mixed sensor with the same shape library, it generates, no frame it draws comes near the
readout's full scale, and it holds out the evaluation suites' shapes at their own parameters."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.scene import Scene, load_scene
from synth.sensors.strips.config import StimulusKind, StripStimuli, allowed_intervals
from synth.sensors.strips.stimuli import ContactGenerator
from synth.suite import load_suite
from tests.synth.test_unseen_suite import SHAPING  # the parameters that shape a contact of each kind

#: a family's fixed value (a washer's 5 mm) stands for this much around it: a scene that draws 4.9 mm
#: washers has not held 5 mm ones out
NEAR = {"force_n": 0.1, "angle_deg": 2.0, "hole_fraction": 0.02, "tilt": 0.05}
NEAR_MM = 0.2


def _allowed(kind: StimulusKind, name: str) -> list[tuple[float, float]]:
    lo, hi = getattr(kind, name)
    if lo == hi:
        near = NEAR.get(name, NEAR_MM)
        lo, hi = lo - near, hi + near
    return allowed_intervals(lo, hi, kind.holdouts(name))


def _overlap(a: list[tuple[float, float]], b: list[tuple[float, float]]) -> bool:
    return any(min(e, f) > max(s, t) for s, e in a for t, f in b)


def can_draw(training: StripStimuli, shape: StimulusKind) -> bool:
    """Whether some kind of ``training`` draws contacts of ``shape``'s kind within all of its
    shaping parameters' ranges (minus both sides' holdouts)."""
    return any(
        spec.kind == shape.kind and all(_overlap(_allowed(spec, p), _allowed(shape, p)) for p in SHAPING[shape.kind])
        for spec in training.kinds
    )


def drawn_counts(stimuli: StripStimuli) -> set[int]:
    lo, hi = stimuli.count
    weights = stimuli.count_weights or (1.0,) * (hi - lo + 1)
    return {lo + i for i, w in enumerate(weights) if w > 0}


def held_out(training: StripStimuli, family: StripStimuli) -> bool:
    """A family is held out of a training scene when one of its shapes, or every contact count it
    presses, is never drawn in training."""
    counts = set(range(family.count[0], family.count[1] + 1)) - {0}
    if not counts & drawn_counts(training):
        return True
    return any(not can_draw(training, shape) for shape in family.kinds)


@pytest.fixture(scope="module")
def wide() -> Scene:
    return load_scene("strips16_wide")


@pytest.fixture(scope="module")
def mixed() -> Scene:
    return load_scene("strips16_mixed")


def test_same_sensor_and_shape_library_as_the_mixed_scene(wide: Scene, mixed: Scene) -> None:
    for part in ("geometry", "layers", "piezo", "readout"):
        assert getattr(wide.sensor, part) == getattr(mixed.sensor, part), part
    assert wide.outputs == mixed.outputs and wide.noise == mixed.noise
    assert sorted(k.kind for k in wide.sensor.stimuli.kinds) == sorted(k.kind for k in mixed.sensor.stimuli.kinds)


def test_every_range_reaches_at_least_as_far_as_the_mixed_scene(wide: Scene, mixed: Scene) -> None:
    """Widened, never narrowed: each of mixed's kinds (matched in order) draws within the wide
    kind's bounds, the top of every size and force range at least as high."""
    for old, new in zip(mixed.sensor.stimuli.kinds, wide.sensor.stimuli.kinds, strict=True):
        assert old.kind == new.kind
        for name in SHAPING[old.kind]:
            (a, b), (c, d) = getattr(old, name), getattr(new, name)
            assert c <= a and d >= b, (old.kind, name, (a, b), (c, d))
    assert wide.sensor.stimuli.count[1] > mixed.sensor.stimuli.count[1]


def test_generates_below_the_readouts_full_scale(wide: Scene) -> None:
    clean = wide.with_noise(False)
    full_scale = clean.sensor.readout.full_scale_v
    frames = simulate_shard(clean, seed=11, index=0, size=600)
    readings = frames["readings"]
    assert readings.shape[0] == 600
    assert np.isfinite(readings).all() and np.isfinite(frames["pressure"]).all()
    assert readings.max() < 0.9 * full_scale
    assert (readings.max(axis=1) > clean.sensor.readout.offset_v + 0.05).mean() > 0.9  # touches are read


@pytest.mark.parametrize("index", range(8))
def test_strongest_single_contact_of_every_kind_stays_below_full_scale(wide: Scene, index: int) -> None:
    """Each kind at its top force and at either end of its sizes (the most concentrated and the
    largest shape), centred on the array: no reading saturates the ADC."""
    stimuli = wide.sensor.stimuli
    spec = stimuli.kinds[index]
    full_scale = wide.sensor.readout.full_scale_v
    for end in (0, 1):
        sizes = {name: (getattr(spec, name)[end],) * 2 for name in ("radius_mm", "width_mm", "length_mm")}
        top = dataclasses.replace(spec, force_n=(spec.force_n[1],) * 2, holdout=(), **sizes)
        one = dataclasses.replace(
            stimuli, kinds=(top,), count=(1, 1), count_weights=(), empty_fraction=0.0, margin_mm=10.0
        )
        scene = dataclasses.replace(wide, sensor=dataclasses.replace(wide.sensor, stimuli=one)).with_noise(False)
        readings = simulate_shard(scene, seed=3, index=0, size=64)["readings"]
        assert readings.max() < 0.95 * full_scale, (spec.kind, end, float(readings.max()))


def test_held_out_check_can_fail(mixed: Scene) -> None:
    """The check itself: without their holdouts, mixed's rings draw the ood suite's washers."""
    washers = load_suite("strips16_ood").family("washer").scene.sensor.stimuli
    stimuli = mixed.sensor.stimuli
    assert held_out(stimuli, washers)
    open_kinds = tuple(dataclasses.replace(k, holdout=()) for k in stimuli.kinds)
    assert not held_out(dataclasses.replace(stimuli, kinds=open_kinds), washers)


def test_ood_suite_stays_held_out(wide: Scene, mixed: Scene) -> None:
    suite = load_suite("strips16_ood")
    before = {f.name for f in suite.families if held_out(mixed.sensor.stimuli, f.scene.sensor.stimuli)}
    after = {f.name for f in suite.families if held_out(wide.sensor.stimuli, f.scene.sensor.stimuli)}
    assert {"washer", "two_washers", "ring_terminal", "tilted_block"} <= before
    # mixed's tilted blocks, nearly flat, draw the 30- and 60-degree blocks; the wide scene holds them out
    assert before | {"block_30deg", "block_60deg"} <= after, (before | {"block_30deg", "block_60deg"}) - after


#: the unseen-shape suite's families (strips16_unseen), each by the interval of the parameter that
#: keeps it out of the wide scene: (kind, parameter, lo, hi)
UNSEEN = {
    "knuckle": ("sphere", "radius_mm", 15.0, 20.0),
    "two_knuckles": ("sphere", "radius_mm", 14.0, 18.0),
    "bottle_cap": ("punch", "radius_mm", 7.5, 10.0),
    "stylus": ("punch", "radius_mm", 0.25, 0.5),
    "feather_touch": ("sphere", "force_n", 0.06, 0.18),
    "heavy_pad": ("block", "force_n", 9.0, 14.0),
    "card_edge_along_strip": ("edge", "radius_mm", 0.05, 0.15),
    "pen_across": ("edge", "radius_mm", 3.5, 4.5),
    "flat_bar": ("block", "length_mm", 30.0, 40.0),
    "thin_rim": ("ring", "hole_fraction", 0.86, 0.93),
    "tabbed_coin_cell": ("terminal", "hole_fraction", 0.0, 0.0),
    "broad_fingertip": ("blob", "width_mm", 5.0, 7.0),
}


def test_unseen_shapes_are_never_drawn(wide: Scene) -> None:
    """20,000 frames of drawn contacts: none inside a held-out interval of its kind, and no frame of
    five contacts (the five fingertips), while every kind and six contacts are drawn."""
    stimuli = wide.sensor.stimuli
    contacts = ContactGenerator(wide.sensor, rasterize=False).draw_contacts(20_000, np.random.default_rng(5))
    assert 5 not in set(contacts["count"].tolist()) and 6 in set(contacts["count"].tolist())
    kinds = np.array([k.kind for k in stimuli.kinds])[contacts["spec"]]
    present = contacts["present"]
    for family, (kind, name, lo, hi) in UNSEEN.items():
        of_kind = present & (kinds == kind)
        assert of_kind.sum() > 500, kind
        value = contacts[name][of_kind]
        inside = (value >= lo) & (value <= hi) if hi > lo else np.abs(value - lo) < 0.02
        assert not inside.any(), (family, value[inside][:5])


def test_unseen_suite_stays_held_out(wide: Scene) -> None:
    """Every family of the unseen suite is held out at the suite's own parameters (five fingertips
    by their count)."""
    suite = load_suite("strips16_unseen")
    assert set(UNSEEN) | {"five_fingertips"} == set(suite.names)
    for family in suite.families:
        assert held_out(wide.sensor.stimuli, family.scene.sensor.stimuli), family.name
    five = suite.family("five_fingertips").scene.sensor.stimuli
    assert not held_out(dataclasses.replace(wide.sensor.stimuli, count_weights=()), five)
