"""Contacts placed as the parts of one rigid object (``[strips.stimuli.object]``) and the flat punch
pressed off its centre (``tilt`` on a punch): placement against its definition, config errors, the
punch's moment, and scenes without either drawing exactly what they did."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from synth.errors import ConfigError
from synth.scene import Scene, load_scene, parse_scene
from synth.sensors.strips.config import ContactObject, StimulusKind
from synth.sensors.strips.stimuli import ContactGenerator
from tests.synth.test_strips_shapes import one_contact


def with_stimuli(scene: Scene, **changes: object) -> Scene:
    stimuli = dataclasses.replace(scene.sensor.stimuli, **changes)  # type: ignore[arg-type]
    return dataclasses.replace(scene, sensor=dataclasses.replace(scene.sensor, stimuli=stimuli))


@pytest.fixture(scope="module")
def strips16() -> Scene:
    return load_scene("strips16")


def test_parts_keep_their_shape_turn_together_and_stay_inside_the_margin(strips16: Scene) -> None:
    offsets = ((-6.0, -2.0), (6.0, -2.0), (0.0, 5.0))
    obj = ContactObject(offsets_mm=offsets, rotation_deg=(0.0, 360.0), scale=(1.0, 1.5))
    kind = StimulusKind("block", width_mm=(2.0, 2.0), length_mm=(6.0, 6.0), angle_deg=(10.0, 10.0))
    scene = with_stimuli(strips16, count=(3, 3), margin_mm=4.0, kinds=(kind,), object=obj)
    c = ContactGenerator(scene.sensor, rasterize=False).draw_contacts(400, np.random.default_rng(3))
    xy = np.stack([c["x_mm"], c["y_mm"]], -1)
    ref = np.asarray(offsets)
    # pairwise distances are the offsets' distances times one scale per frame, within its range
    d = np.linalg.norm(xy[:, :, None] - xy[:, None, :], axis=-1)
    d_ref = np.linalg.norm(ref[:, None] - ref[None, :], axis=-1)
    scale = d[:, 0, 1] / d_ref[0, 1]
    assert np.allclose(d, scale[:, None, None] * d_ref, atol=1e-9)
    assert scale.min() >= 1.0 and scale.max() <= 1.5 and scale.std() > 0.1
    # the turn of the first pair's direction is the turn of every part's own angle
    v = xy[:, 1] - xy[:, 0]
    turn = np.rad2deg(np.arctan2(v[:, 1], v[:, 0]) - np.arctan2(*(ref[1] - ref[0])[::-1]))
    assert np.allclose(np.cos(np.deg2rad(c["angle_deg"] - 10.0 - turn[:, None])), 1.0)
    assert np.ptp(np.mod(turn, 360.0)) > 300  # the whole turn is drawn
    assert xy.min() >= 4.0 - 1e-9 and xy.max() <= 40.0 - 4.0 + 1e-9


def test_part_kinds_take_one_kind_per_part(strips16: Scene) -> None:
    kinds = (StimulusKind("sphere", radius_mm=(10.0, 12.0)), StimulusKind("punch", radius_mm=(1.0, 2.0)))
    obj = ContactObject(offsets_mm=((0.0, 0.0), (10.0, 0.0)), part_kinds=True)
    scene = with_stimuli(strips16, count=(2, 2), kinds=kinds, object=obj)
    c = ContactGenerator(scene.sensor, rasterize=False).draw_contacts(200, np.random.default_rng(4))
    assert (c["spec"] == [0, 1]).all()
    assert (c["radius_mm"][:, 0] >= 10.0).all() and (c["radius_mm"][:, 1] <= 2.0).all()
    assert np.allclose(c["x_mm"][:, 1] - c["x_mm"][:, 0], 10.0) and np.allclose(c["y_mm"][:, 1], c["y_mm"][:, 0])


@pytest.mark.parametrize(
    ("stimuli", "message"),
    [
        ({"count": [3, 3], "object": {"offsets_mm": [[0.0, 0.0], [5.0, 0.0]]}}, "the object has 2 parts"),
        (
            {"count": [2, 2], "object": {"offsets_mm": [[0.0, 0.0], [5.0, 0.0]], "part_kinds": True}},
            "one kind per part",
        ),
        ({"count": [2, 2], "object": {"offsets_mm": [[-15.0, 0.0], [15.0, 0.0]]}, "margin_mm": 6.0}, "do not fit"),
        ({"count": [1, 1], "object": {"offsets_mm": []}}, "at least one part"),
        ({"count": [1, 1], "object": {"offsets_mm": [[0.0, 0.0]], "scale": [0.0, 1.0]}}, "scale[0]"),
    ],
)
def test_object_config_errors_name_the_problem(strips16: Scene, stimuli: dict[str, object], message: str) -> None:
    data = strips16.to_dict()
    data["strips"]["stimuli"] = {**data["strips"]["stimuli"], **stimuli}
    with pytest.raises(ConfigError, match=message.replace("[", r"\[")):
        parse_scene(data, "test")


def test_scenes_without_an_object_keep_their_digest_and_frames(strips16: Scene) -> None:
    """The new field is left out of a scene's dict while unset; the same seed draws the same
    contacts with or without the code path (an object of one part at the centre moves nothing but
    the centres)."""
    assert "object" not in strips16.to_dict()["strips"]["stimuli"]
    plain = ContactGenerator(strips16.sensor, rasterize=False).draw_contacts(50, np.random.default_rng(9))
    placed_scene = with_stimuli(strips16, object=ContactObject(offsets_mm=((0.0, 0.0), (0.0, 0.0))))
    placed = ContactGenerator(placed_scene.sensor, rasterize=False).draw_contacts(50, np.random.default_rng(9))
    for key in ("count", "spec", "force_n", "radius_mm"):
        assert np.array_equal(plain[key], placed[key]), key
    assert not np.array_equal(plain["x_mm"], placed["x_mm"])


def test_punch_off_its_centre_carries_its_force_and_moment() -> None:
    """Boussinesq with a moment: ``p = F (1 + t s / a) / (2 pi a sqrt(a^2 - r^2))``; its centre of
    pressure lies ``t a / 3`` from the centre along ``angle_deg``, the force is unchanged, and an
    untilted punch is bit for bit what it was."""
    h, a = 0.25, 4.0
    flat = one_contact("punch", h=h, radius_mm=a)
    y, x = (np.indices(flat.shape) + 0.5) * h - 40 * h
    assert np.array_equal(flat, one_contact("punch", h=h, radius_mm=a, tilt=0.0, angle_deg=70.0))
    for tilt, angle in ((1.0, 0.0), (0.5, 90.0), (-0.8, 30.0)):
        pushed = one_contact("punch", h=h, radius_mm=a, tilt=tilt, angle_deg=angle)
        assert pushed.sum() == pytest.approx(flat.sum(), rel=1e-9)
        assert (pushed >= 0).all()
        theta = np.deg2rad(angle)
        shift = (pushed * (x * np.cos(theta) + y * np.sin(theta))).sum() / pushed.sum()
        across = (pushed * (-x * np.sin(theta) + y * np.cos(theta))).sum() / pushed.sum()
        assert shift == pytest.approx(tilt * a / 3, rel=0.06), (tilt, angle)
        assert abs(across) < 0.02


def test_a_scene_with_an_object_round_trips_through_its_dict_and_toml() -> None:
    """Datasets store their scene (and resume against it): the object survives both."""
    import tomllib

    from synth.config import dumps_toml
    from synth.suite import load_suite

    scene = load_suite("strips16_unseen2").family("thumb_and_fingertips").scene
    data = scene.to_dict()
    assert data["strips"]["stimuli"]["object"]["part_kinds"] is True
    assert parse_scene(data, "dict") == scene
    assert parse_scene(tomllib.loads(dumps_toml(data)), "toml") == scene
    assert parse_scene(tomllib.loads(dumps_toml(data)), "toml").digest == scene.digest
