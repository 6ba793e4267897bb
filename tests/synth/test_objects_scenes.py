"""The object scenes of the strip array (synth/scenes/strips16_objects_*.toml): training frames whose
contacts are the parts of one rigid object. They parse as strips16_wide's sensor, generate below the
readout's full scale, and hold out, in drawn frames, what the evaluation suites press: the ood suite's
block angles and round 1's shapes (as strips16_wide does), and round 2's objects
(synth/suites/strips16_unseen2.toml) at their own parameters. Each round-2 check is a predicate on
drawn contacts ("this frame could be one of the family's"), itself checked on the family's own frames."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.errors import ConfigError
from synth.scene import Scene, load_scene
from synth.sensors.strips.config import ContactObject
from synth.sensors.strips.stimuli import ContactGenerator
from synth.suite import load_suite
from tests.paths import REPO_ROOT
from tests.synth.test_wide_scene import UNSEEN, held_out

NAMES = sorted(p.stem for p in (Path(REPO_ROOT) / "synth" / "scenes").glob("strips16_objects_*.toml"))
#: the ood suite's block angles that strips16_wide holds out (degrees, modulo 180)
BLOCK_WINDOWS = ((25.0, 35.0), (55.0, 65.0), (115.0, 125.0), (145.0, 155.0))

Contacts = dict[str, np.ndarray]


def draw(scene: Scene, n: int, seed: int) -> tuple[Contacts, np.ndarray]:
    """Drawn contacts (no rasterising) and each slot's kind name."""
    contacts = ContactGenerator(scene.sensor, rasterize=False).draw_contacts(n, np.random.default_rng(seed))
    names = np.array([k.kind for k in scene.sensor.stimuli.kinds])[contacts["spec"]]
    return contacts, np.where(contacts["present"], names, "")


def within(v: np.ndarray, lo: float, hi: float) -> np.ndarray:
    return np.asarray((v >= lo) & (v <= hi))


def _any(mask: np.ndarray) -> np.ndarray:
    return np.asarray(mask.any(axis=1))


def _pairs(c: Contacts, kinds: np.ndarray, ok: Callable[[int, int], np.ndarray]) -> np.ndarray:
    """Frames where some two present slots i != j satisfy ``ok(i, j)`` (a per-frame mask)."""
    k = kinds.shape[1]
    out = np.zeros(len(kinds), dtype=bool)
    for i in range(k):
        for j in range(k):
            if i != j:
                out |= ok(i, j)
    return out


def _line_angle(c: Contacts, i: int, j: int) -> np.ndarray:
    return np.rad2deg(np.arctan2(c["y_mm"][:, j] - c["y_mm"][:, i], c["x_mm"][:, j] - c["x_mm"][:, i])) % 180.0


def _distance(c: Contacts, i: int, j: int) -> np.ndarray:
    return np.hypot(c["x_mm"][:, j] - c["x_mm"][:, i], c["y_mm"][:, j] - c["y_mm"][:, i])


def _near_angle(angle: np.ndarray, target: float, tol: float) -> np.ndarray:
    return np.abs((angle - target + 90.0) % 180.0 - 90.0) <= tol


def _studs(c: Contacts, kinds: np.ndarray) -> np.ndarray:  # LEGO studs: punches of 2.4 mm radius
    return _any((kinds == "punch") & within(c["radius_mm"], 2.2, 2.6))


def _pins(c: Contacts, kinds: np.ndarray) -> np.ndarray:  # DIP pin shoulders: punches of 0.6-0.8 mm
    return _any((kinds == "punch") & within(c["radius_mm"], 0.6, 0.8))


def _coin(c: Contacts, kinds: np.ndarray) -> np.ndarray:  # a punch of 10-13 mm tilted 0.5 or more
    return _any((kinds == "punch") & within(c["radius_mm"], 10.0, 13.0) & (np.abs(c["tilt"]) >= 0.5))


def _fingertips_along_row(c: Contacts, kinds: np.ndarray) -> np.ndarray:
    """Three fingertips (6-9 mm) on one line within 3 degrees of a row, two of them 15-18 mm apart."""
    if kinds.shape[1] < 3:
        return np.zeros(len(kinds), dtype=bool)
    tips = ((kinds == "sphere") & within(c["radius_mm"], 6.0, 9.0))[:, :3].all(axis=1)
    pairs = ((0, 1), (0, 2), (1, 2))
    on_row = np.all([_near_angle(_line_angle(c, i, j), 0.0, 3.0) for i, j in pairs], axis=0)
    spaced = np.any([within(_distance(c, i, j), 15.0, 18.0) for i, j in pairs], axis=0)
    return (c["count"] == 3) & tips & on_row & spaced


def _pinch_along_column(c: Contacts, kinds: np.ndarray) -> np.ndarray:
    sphere, r = kinds == "sphere", c["radius_mm"]
    return (c["count"] == 2) & _pairs(
        c,
        kinds,
        lambda i, j: (
            sphere[:, i]
            & sphere[:, j]
            & within(r[:, i], 9.0, 12.0)
            & within(r[:, j], 6.0, 8.0)
            & within(_distance(c, i, j), 12.0, 30.0)
            & _near_angle(_line_angle(c, i, j), 90.0, 3.0)
        ),
    )


def _cross(c: Contacts, kinds: np.ndarray) -> np.ndarray:  # bars 3-5 x 18-24 mm crossing at their middles
    bar = (kinds == "block") & within(c["width_mm"], 3.0, 5.0) & within(c["length_mm"], 18.0, 24.0)
    return _pairs(
        c,
        kinds,
        lambda i, j: (
            bar[:, i]
            & bar[:, j]
            & (_distance(c, i, j) < 0.5)
            & _near_angle(c["angle_deg"][:, i] - c["angle_deg"][:, j], 90.0, 2.0)
        ),
    )


def _angle_bracket(c: Contacts, kinds: np.ndarray) -> np.ndarray:  # 20 x 4 and 16 x 4 mm arms
    block, w, length = kinds == "block", c["width_mm"], c["length_mm"]
    return _pairs(
        c,
        kinds,
        lambda i, j: (
            block[:, i]
            & block[:, j]
            & within(w[:, i], 3.8, 4.2)
            & within(w[:, j], 3.8, 4.2)
            & within(length[:, i], 19.8, 20.2)
            & within(length[:, j], 15.8, 16.2)
        ),
    )


def _thumb(c: Contacts, kinds: np.ndarray) -> np.ndarray:  # a thumb's pad of 10-14 mm beside three fingertips
    return (c["count"] == 4) & _any((kinds == "sphere") & within(c["radius_mm"], 10.0, 14.0))


def _fork(c: Contacts, kinds: np.ndarray) -> np.ndarray:  # four tines 1.5-2 mm wide, 16-20 mm long
    tine = (kinds == "block") & within(c["width_mm"], 1.5, 2.0) & within(c["length_mm"], 16.0, 20.0)
    return tine.sum(axis=1) >= 4


def _blobs(c: Contacts, kinds: np.ndarray) -> np.ndarray:  # the rolling thumb's soft pads
    return _any(kinds == "blob")


def _edges(c: Contacts, kinds: np.ndarray) -> np.ndarray:  # chopsticks
    return _any(kinds == "edge")


#: round 2's families, each with the predicate that recognises its frames
ROUND2: dict[str, Callable[[Contacts, np.ndarray], np.ndarray]] = {
    "lego_2x4": _studs,
    "lego_2x2_square": _studs,
    "dip8_chip": _pins,
    "coin_off_centre": _coin,
    "fingertips_along_row": _fingertips_along_row,
    "pinch_along_column": _pinch_along_column,
    "cross_bracket": _cross,
    "angle_bracket": _angle_bracket,
    "thumb_and_fingertips": _thumb,
    "fork_tines": _fork,
    "rolling_thumb": _blobs,
    "chopsticks": _edges,
}


@pytest.fixture(scope="module")
def scenes() -> dict[str, Scene]:
    return {name: load_scene(name) for name in NAMES}


@pytest.fixture(scope="module")
def drawn(scenes: dict[str, Scene]) -> dict[str, tuple[Contacts, np.ndarray]]:
    return {name: draw(scene, 6000, seed=5) for name, scene in scenes.items()}


def assert_wide_sensor(scenes: dict[str, Scene]) -> None:
    """Every scene is strips16_wide's sensor (a training scene of the same model), outputs and noise."""
    wide = load_scene("strips16_wide")
    for name, scene in scenes.items():
        for part in ("geometry", "layers", "piezo", "readout"):
            assert getattr(scene.sensor, part) == getattr(wide.sensor, part), (name, part)
        assert scene.outputs == wide.outputs and scene.noise == wide.noise, name


def assert_pressed_below_full_scale(scene: Scene, seed: int, size: int = 120) -> None:
    """Noise-free frames are finite, non-negative, read, and below 0.9 of the ADC's full scale."""
    clean = scene.with_noise(False)
    frames = simulate_shard(clean, seed=seed, index=0, size=size)
    readings, pressure = frames["readings"], frames["pressure"]
    assert readings.shape == (size, 32) and pressure.shape == (size, 16, 16)
    assert np.isfinite(readings).all() and (pressure >= 0).all()
    assert readings.max() < 0.9 * clean.sensor.readout.full_scale_v
    # nearly every frame is read: a large punch at its lightest force may stay faint
    assert (readings.max(axis=1) > clean.sensor.readout.offset_v + 0.02).mean() > 0.9


def test_the_object_scenes_exist_and_share_the_wide_scenes_sensor(scenes: dict[str, Scene]) -> None:
    assert len(scenes) >= 8
    assert_wide_sensor(scenes)


@pytest.mark.parametrize("name", NAMES)
def test_generates_pressed_frames_below_full_scale(scenes: dict[str, Scene], name: str) -> None:
    assert_pressed_below_full_scale(scenes[name], seed=11)


def test_objects_parts_keep_their_arrangement(drawn: dict[str, tuple[Contacts, np.ndarray]]) -> None:
    """A rigid object: in the 2 x 2 grid the first two parts lie one pitch apart along the object's
    (near-row) axis, whatever the frame."""
    c, _ = drawn["strips16_objects_grid_square"]
    angle = _line_angle(c, 0, 1)
    assert _near_angle(angle, 0.0, 12.01).all()
    assert within(_distance(c, 0, 1), 3.5 - 1e-9, 14.0 + 1e-9).all()


def test_round2_predicates_recognise_their_own_families() -> None:
    """The checks below can fail: each predicate flags (nearly) every frame its family draws."""
    suite = load_suite("strips16_unseen2")
    assert set(ROUND2) == set(suite.names)
    for family in suite.families:
        contacts, kinds = draw(family.scene, 400, seed=3)
        share = ROUND2[family.name](contacts, kinds).mean()
        assert share > 0.97, (family.name, share)


@pytest.mark.parametrize("name", NAMES)
def test_round2_objects_are_never_drawn(drawn: dict[str, tuple[Contacts, np.ndarray]], name: str) -> None:
    contacts, kinds = drawn[name]
    for family, predicate in ROUND2.items():
        hits = predicate(contacts, kinds)
        assert not hits.any(), (name, family, int(hits.sum()))


@pytest.mark.parametrize("name", NAMES)
def test_wide_scenes_holdouts_stay_out(
    scenes: dict[str, Scene], drawn: dict[str, tuple[Contacts, np.ndarray]], name: str
) -> None:
    """strips16_wide's holdouts in drawn frames: the ood suite's block angles after the object's turn,
    round 1's shape intervals, five contacts (the five fingertips); and the ood families that
    strips16_wide holds out stay held out by the scene's ranges."""
    contacts, kinds = drawn[name]
    present = kinds != ""
    assert present.any(axis=1).all()
    assert 5 not in set(contacts["count"].tolist())
    blocks = kinds == "block"
    angles = contacts["angle_deg"][blocks] % 180.0
    for lo, hi in BLOCK_WINDOWS:
        assert not within(angles, lo, hi).any(), (name, lo, hi)
    for family, (kind, parameter, lo, hi) in UNSEEN.items():
        value = contacts[parameter][kinds == kind]
        inside = within(value, lo, hi) if hi > lo else np.abs(value - lo) < 0.02
        assert not inside.any(), (name, family)
    # feather touches stay outside the forces' bounds of every kind
    assert (contacts["force_n"][present] >= 0.2).all()
    stimuli = scenes[name].sensor.stimuli
    for ood in load_suite("strips16_ood").families:
        if ood.name in ("block_30deg", "block_60deg", "washer", "two_washers", "ring_terminal", "tilted_block"):
            assert held_out(stimuli, ood.scene.sensor.stimuli), (name, ood.name)


def test_block_angle_check_can_fail(scenes: dict[str, Scene]) -> None:
    """Without its rotation holdout the cross's bars are drawn at the ood suite's block angles."""
    scene = scenes["strips16_objects_cross"]
    stimuli = scene.sensor.stimuli
    assert stimuli.object is not None
    open_object = dataclasses.replace(stimuli.object, rotation_holdout=())
    opened = dataclasses.replace(
        scene, sensor=dataclasses.replace(scene.sensor, stimuli=dataclasses.replace(stimuli, object=open_object))
    )
    contacts, kinds = draw(opened, 2000, seed=5)
    angles = contacts["angle_deg"][kinds == "block"] % 180.0
    assert within(angles, 25.0, 35.0).any()


def test_rotation_holdout_is_drawn_around_and_validated() -> None:
    obj = ContactObject(offsets_mm=((0.0, 0.0),), rotation_deg=(0.0, 90.0), rotation_holdout=((10.0, 80.0),))
    assert obj.rotation_holdout == ((10.0, 80.0),)
    with pytest.raises(ConfigError, match="rotation_holdout"):
        ContactObject(rotation_deg=(0.0, 10.0), rotation_holdout=((-1.0, 11.0),))
    with pytest.raises(ConfigError, match="empty"):
        ContactObject(rotation_deg=(0.0, 10.0), rotation_holdout=((5.0, 5.0),))
    scene = load_scene("strips16_objects_cross")
    stimuli = scene.sensor.stimuli
    assert stimuli.object is not None
    narrow = dataclasses.replace(stimuli.object, rotation_deg=(0.0, 90.0), rotation_holdout=((10.0, 80.0),))
    turned = dataclasses.replace(
        scene, sensor=dataclasses.replace(scene.sensor, stimuli=dataclasses.replace(stimuli, object=narrow))
    )
    contacts, _ = draw(turned, 3000, seed=1)
    rotation = contacts["angle_deg"][:, 0]  # the first bar lies at the object's rotation
    assert ((rotation < 10.0) | (rotation > 80.0)).all()
    assert (rotation < 10.0).mean() == pytest.approx(0.5, abs=0.05)
