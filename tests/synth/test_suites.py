"""Evaluation suites: the strips16_ood families, their held-out parameters, reproducible frames, and
clear errors for a bad suite file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from synth.errors import ConfigError
from synth.scene import load_scene
from synth.sensors.strips.config import allowed_intervals
from synth.suite import available_suites, load_suite, parse_suite, suite_frames

#: the families the issue names, by their names in strips16_ood
ISSUE_FAMILIES = (
    "washer",
    "two_washers",
    "ring_terminal",
    "block_30deg",
    "block_60deg",
    "tilted_block",
    "three_spheres",
    "twin_spheres",
    "diagonal_edge",
)


def _kind(family_scene, kind: str):  # type: ignore[no-untyped-def]
    return [k for k in family_scene.sensor.stimuli.kinds if k.kind == kind]


def _held_out(value: float, name: str, kind: str, tilt: bool | None = None) -> bool:
    """True if no strips16_mixed entry of ``kind`` can draw ``value`` of parameter ``name``."""
    mixed = load_scene("strips16_mixed").sensor.stimuli.kinds
    for spec in mixed:
        if spec.kind != kind or (tilt is not None and (spec.tilt != (0.0, 0.0)) != tilt):
            continue
        lo, hi = getattr(spec, name)
        if any(a <= value <= b for a, b in allowed_intervals(lo, hi, spec.holdouts(name))):
            return False
    return True


def test_ood_suite_holds_the_issue_families_on_the_strips16_sensor() -> None:
    suite = load_suite("strips16_ood")
    assert "strips16_ood" in available_suites()
    assert set(ISSUE_FAMILIES) <= set(suite.names)
    for family in suite.families:
        scene = family.scene
        assert scene.noise and scene.task == "strips"
        # the same sensor as strips16: only the stimuli differ
        sensor = {k: v for k, v in scene.to_dict()["strips"].items() if k != "stimuli"}
        assert sensor == {k: v for k, v in load_scene("strips16").to_dict()["strips"].items() if k != "stimuli"}
        for spec in scene.sensor.stimuli.kinds:
            assert spec.force_n == (1.0, 6.0)  # the issue's 1-6 N
    assert suite.family("twin_spheres").scene.sensor.stimuli.twin_fraction == 1.0
    assert suite.family("three_spheres").scene.sensor.stimuli.count == (3, 3)
    assert suite.family("two_washers").scene.sensor.stimuli.count == (2, 2)


def test_ood_parameters_are_never_drawn_in_training() -> None:
    suite = load_suite("strips16_ood")
    washer = _kind(suite.family("washer").scene, "ring")[0]
    assert _held_out(washer.radius_mm[0], "radius_mm", "ring") and washer.radius_mm[0] == washer.radius_mm[1]
    for name, angle in (("block_30deg", 30.0), ("block_60deg", 60.0)):
        block = _kind(suite.family(name).scene, "block")[0]
        assert block.angle_deg == (angle, angle)
        assert _held_out(angle, "angle_deg", "block", tilt=False)
        assert _held_out(180.0 - angle, "angle_deg", "block", tilt=False)  # the mirror image too
    edge = _kind(suite.family("diagonal_edge").scene, "edge")[0]
    assert edge.angle_deg == (45.0, 45.0) and _held_out(45.0, "angle_deg", "edge")
    assert edge.length_mm[0] >= 40.0
    terminal = _kind(suite.family("ring_terminal").scene, "terminal")[0]
    assert _held_out(terminal.radius_mm[0], "radius_mm", "terminal")
    tilted = _kind(suite.family("tilted_block").scene, "block")[0]
    assert all(_held_out(v, "length_mm", "block", tilt=True) for v in np.linspace(*tilted.length_mm, 5))


def test_suite_frames_are_reproducible_and_per_family(tmp_path: Path) -> None:
    suite = load_suite("strips16_ood")
    a = suite_frames(suite, 6, seed=3)
    b = suite_frames(suite, 6, seed=3)
    c = suite_frames(suite, 6, seed=4)
    assert list(a) == list(suite.names)
    for name in a:
        assert a[name]["readings"].shape == (6, 32)
        assert np.array_equal(a[name]["readings"], b[name]["readings"])
    assert not np.array_equal(a["washer"]["readings"], c["washer"]["readings"])
    kinds = a["ring_terminal"]["latent_kind"][:, 0]
    assert (kinds == 5).all()  # "terminal" in synth.stimuli.KINDS
    assert (a["three_spheres"]["latent_n_contacts"] == 3).all()


def _suite(**family: object) -> dict[str, object]:
    return {"name": "t", "base": "strips16", "families": [{"name": "f", **family}]}


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"name": "t", "base": "strips16"}, "at least one"),
        ({"name": "t", "base": "strips16", "families": [{"name": "a"}, {"name": "a"}]}, "appears twice"),
        ({**_suite(), "colour": 1}, "colour: unknown key"),
        (_suite(colour=1), "colour: unknown key"),
        ({**_suite(), "base": "nope"}, "unknown scene"),
        (_suite(strips={"stimuli": {"count": [3, 1]}}), "non-decreasing"),
        ({**_suite(), "frames": 0}, "frames"),
    ],
)
def test_bad_suites_are_refused_with_the_key_named(data: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_suite(data, "t.toml")


def test_a_family_replaces_stimuli_but_merges_the_sensor() -> None:
    suite = parse_suite(
        _suite(strips={"layers": {"cover_mm": 2.0}, "stimuli": {"count": [1, 1], "kinds": [{"kind": "punch"}]}}),
        "t.toml",
    )
    scene = suite.family("f").scene
    assert scene.sensor.layers.cover_mm == 2.0 and scene.sensor.layers.poisson_ratio == 0.49
    assert [k.kind for k in scene.sensor.stimuli.kinds] == ["punch"]
    assert scene.sensor.stimuli.margin_mm == 0.0  # not strips16's 2 mm: the stimuli table is replaced
    assert scene.name == "t/f"


TINY_SUITE = """
name = "tiny"
base = "strips5"
frames = 30

[[families]]
name = "rings"
[families.strips.stimuli]
count = [1, 1]
margin_mm = 3.0
[[families.strips.stimuli.kinds]]
kind = "ring"
force_n = [1.0, 3.0]
radius_mm = [2.0, 3.0]

[[families]]
name = "pairs"
[families.strips.stimuli]
count = [2, 2]
[[families.strips.stimuli.kinds]]
kind = "sphere"
force_n = [1.0, 3.0]
"""


def test_eval_and_bench_report_every_family(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from tactile_learn.cli import main

    (workdir / "tiny.toml").write_text(TINY_SUITE)
    argv = ["eval", "--task", "strips", "--suite", "tiny.toml", "--method", "intersection", "--json", "e.json"]
    assert main(argv) == 0
    result = json.loads((workdir / "e.json").read_text())
    assert set(result["families"]) == {"rings", "pairs"}
    assert result["n_frames_per_family"] == {"rings": 30, "pairs": 30}
    rings, pairs = result["families"]["rings"]["pearson_r_mean"], result["families"]["pairs"]["pearson_r_mean"]
    assert result["mean_over_families"]["pearson_r_mean"] == pytest.approx((rings + pairs) / 2)
    assert "residual_rel_median" in result["families"]["rings"]
    # the same seed gives the same numbers; another seed other frames
    assert main([*argv[:-2], "--json", "again.json"]) == 0
    assert json.loads((workdir / "again.json").read_text())["families"] == result["families"]
    assert main([*argv[:-2], "--seed", "9", "--json", "other.json"]) == 0
    assert json.loads((workdir / "other.json").read_text())["families"] != result["families"]
    capsys.readouterr()
    assert main(["bench", "--task", "strips", "--suite", "tiny.toml", "--quick", "--json", "b.json"]) == 0
    table = capsys.readouterr().out
    assert "rings" in table and "pairs" in table and "mean_over_families" in table
    bench = json.loads((workdir / "b.json").read_text())
    names = [m["name"] for m in bench["methods"]]
    assert {"intersection", "projection"} <= set(names)
    inter = bench["methods"][names.index("intersection")]
    from tactile_learn.bench import BENCH_SEED

    assert main([*argv[:-2], "--seed", str(BENCH_SEED), "--json", "same.json"]) == 0  # bench's frames
    same = json.loads((workdir / "same.json").read_text())["families"]["rings"]["pearson_r_mean"]
    assert inter["families"]["rings"]["pearson_r_mean"] == pytest.approx(same, rel=1e-12)
    # errors: a suite of another task, neither --data nor --suite
    assert main(["eval", "--task", "fsr", "--suite", "tiny.toml", "--method", "triangulation"]) == 2
    assert main(["eval", "--task", "strips", "--method", "intersection"]) == 2
