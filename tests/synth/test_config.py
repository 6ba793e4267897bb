"""Scene and config validation: every bad value gets an error naming its key."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import pytest
import tomllib

from synth.config import dumps_toml, from_dict, param, replace, to_dict
from synth.errors import ConfigError
from synth.scene import available_scenes, load_scene, parse_scene, scene_differences


@dataclass(frozen=True)
class Inner:
    size_mm: float = param(1.0, lo=0.0, lo_open=True, unit="mm")
    span: tuple[float, float] = param((1.0, 2.0), lo=0.0, ordered=True)


@dataclass(frozen=True)
class Outer:
    count: int = param(3, lo=1, hi=10)
    flag: bool = False
    inner: Inner = param(Inner())
    items: tuple[Inner, ...] = ()


def test_defaults_and_round_trip() -> None:
    obj = from_dict(Outer, {"count": 4, "inner": {"size_mm": 2}, "items": [{"span": [0.5, 0.7]}]})
    assert obj.count == 4 and obj.inner.size_mm == 2.0 and isinstance(obj.inner.size_mm, float)
    assert from_dict(Outer, to_dict(obj)) == obj


@pytest.mark.parametrize(
    ("data", "fragment"),
    [
        ({"cuont": 3}, "cuont: unknown key"),
        ({"count": "3"}, "count: expected int"),
        ({"count": 2.5}, "count: expected an integer"),
        ({"count": True}, "count: expected int"),
        ({"count": 11}, "count: 11 is out of range (must be <= 10)"),
        ({"flag": 1}, "flag: expected true or false"),
        ({"inner": {"size_mm": 0.0}}, "inner.size_mm: 0.0 mm is out of range (must be > 0.0 mm)"),
        ({"inner": {"span": [2.0, 1.0]}}, "inner.span: values must be non-decreasing"),
        ({"inner": {"span": [1.0]}}, "inner.span: expected 2 values"),
        ({"inner": {"span": [1.0, float("nan")]}}, "inner.span[1]: must be finite"),
        ({"items": [{"bogus": 1}]}, "items[0].bogus: unknown key"),
        ({"inner": 3}, "inner: expected a table"),
    ],
)
def test_bad_values_name_their_key(data: dict, fragment: str) -> None:
    with pytest.raises(ConfigError) as info:
        from_dict(Outer, data)
    assert fragment in str(info.value)


def test_replace_validates() -> None:
    obj = Outer()
    assert replace(obj, "inner.size_mm", 3.0).inner.size_mm == 3.0
    with pytest.raises(ConfigError, match=r"inner\.size_mm"):
        replace(obj, "inner.size_mm", -1.0)
    with pytest.raises(ConfigError, match="unknown key"):
        replace(obj, "inner.nope", 1.0)


def test_toml_writer_round_trips_every_shipped_scene() -> None:
    for name in available_scenes():
        scene = load_scene(name)
        text = dumps_toml(scene.to_dict())
        again = parse_scene(tomllib.loads(text), name)
        assert again == scene and again.digest == scene.digest


def test_shipped_scenes_load_and_digests_differ() -> None:
    names = available_scenes()
    assert {"strips16", "strips16_one", "strips5"} <= set(names)
    digests = {load_scene(n).digest for n in names}
    assert len(digests) == len(names)


def test_scene_differences_name_the_keys_the_digest_compares() -> None:
    scene = load_scene("strips16")
    quiet = dataclasses.replace(scene, noise=False, name="other", description="renamed")
    assert scene_differences(scene, scene) == []
    assert scene_differences(scene, quiet) == ["noise: True vs False"]  # name and description are not physics
    other = load_scene("strips5")
    lines = scene_differences(scene, other, limit=2)
    assert len(lines) == 3 and lines[-1].startswith("... and ") and "geometry" in " ".join(lines)


def test_scene_file_errors(tmp_path: Path) -> None:
    base = dumps_toml(load_scene("strips5").to_dict())
    cases = {
        "unknown top key": (
            base.replace('task = "strips"', 'task = "strips"\ncolour = "red"'),
            "colour: unknown key",
        ),
        "unknown sensor key": (
            base.replace("n_rows = 5", "n_rows = 5\nn_rowz = 5"),
            "strips.geometry.n_rowz: unknown key",
        ),
        "out of range": (
            base.replace("adc_bits = 12", "adc_bits = 40"),
            "strips.readout.adc_bits: 40 is out of range",
        ),
        "wrong type": (
            base.replace("pitch_mm = 5.0", 'pitch_mm = "5"'),
            "strips.geometry.pitch_mm: expected float",
        ),
        "cross-field": (base.replace("strip_width_mm = 4.0", "strip_width_mm = 6.0"), "wider than the pitch"),
        "bad output": (
            base.replace('outputs = ["readings"', 'outputs = ["readingz"'),
            "unknown output 'readingz'",
        ),
        "bad task": (base.replace('task = "strips"', 'task = "sonar"'), "task: 'sonar' is not one of"),
        "not toml": ("name = [", "not valid TOML"),
    }
    for label, (text, fragment) in cases.items():
        path = tmp_path / f"{label.replace(' ', '_')}.toml"
        path.write_text(text)
        with pytest.raises(ConfigError) as info:
            load_scene(path)
        assert fragment in str(info.value), label
        assert path.name in str(info.value), label


def test_unknown_scene_name_lists_shipped_ones() -> None:
    with pytest.raises(ConfigError, match=r"shipped scenes: .*strips16"):
        load_scene("strips17")
    with pytest.raises(ConfigError, match="does not exist"):
        load_scene("missing/file.toml")


def test_noise_switch_changes_digest() -> None:
    scene = load_scene("strips16")
    assert scene.with_noise(False).digest != scene.digest
    assert scene.with_noise(False).with_noise(True) == scene


def test_negative_zero_is_read_as_zero_and_its_range_samples() -> None:
    """[0.0, -0.0] passes the min <= max check; numpy's uniform refused it before -0.0 was
    normalised (found by the thermal stress test)."""
    import math

    import numpy as np

    from synth.sensors.thermal import make_simulator

    scene = load_scene("thermal_wns")
    scene = scene.__class__(**{**scene.__dict__, "sensor": replace(scene.sensor, "objects.offset_k", [0.0, -0.0])})
    assert all(math.copysign(1.0, v) == 1.0 for v in scene.sensor.objects.offset_k)
    out = make_simulator(scene).simulate(3, np.random.default_rng(0))
    assert np.isfinite(out["readings"]).all()
