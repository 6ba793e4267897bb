"""Design sweeps: points on a local Dask cluster, resumable, with a table and a recommendation."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from synth.errors import ConfigError

pytest.importorskip("distributed", reason="the cluster extra (dask.distributed) is not installed")

from tactile_learn.cli import main
from tactile_learn.sweep import load_sweep, point_id, point_scene, sweep_points, wire_count

SWEEP = """
name = "tiny"
base = "strips5"
mode = "grid"
[parameters]
"strips.geometry.n_rows+strips.geometry.n_cols" = [4, 5]
"strips.layers.cover_mm" = [0.5, 2.0]
[budget]
train = {train}
val = 64
test = 64
epochs = 1
"""


def _write(tmp_path: Path, train: int = 0, extra: str = "") -> Path:
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP.format(train=train) + extra)
    return path


def test_points_and_their_scenes(tmp_path: Path) -> None:
    config = load_sweep(_write(tmp_path))
    points = sweep_points(config)
    assert len(points) == 4 and len({point_id(p) for p in points}) == 4
    scene = point_scene(config.base, points[0])
    assert scene.sensor.geometry.n_rows == scene.sensor.geometry.n_cols == 4
    assert wire_count(scene) == 8 and scene.sensor.layers.cover_mm == 0.5
    assert point_id(dict(reversed(points[0].items()))) == point_id(points[0])  # order-free ids


def test_bad_sweeps_name_the_problem(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(SWEEP.format(train=0).replace('"strips.layers.cover_mm"', '"strips.layers.nope"'))
    with pytest.raises(ConfigError, match="nope"):
        load_sweep(bad)
    bad.write_text(SWEEP.format(train=0).replace("[0.5, 2.0]", "[0.5, -1.0]"))
    with pytest.raises(ConfigError, match="cover_mm"):
        load_sweep(bad)
    bad.write_text(SWEEP.format(train=0).replace('mode = "grid"', 'mode = "spiral"'))
    with pytest.raises(ConfigError, match="mode"):
        load_sweep(bad)


@pytest.mark.slow
def test_sweep_runs_on_a_local_cluster_and_resumes(tmp_path: Path) -> None:
    config = _write(tmp_path, train=512)
    out = tmp_path / "out"
    assert main(["sweep", "--config", str(config), "--out", str(out), "--workers", "2"]) == 0
    summary = json.loads((out / "sweep.json").read_text())
    assert summary["computed_now"] == 4 and len(summary["points"]) == 4
    for point in summary["points"]:
        assert point["status"] == "ok", point.get("error")
        assert set(point["methods"]) == {"intersection", "projection", "learned"}
        assert (out / "points" / point["id"] / "scene.toml").is_file()
    # a thinner cover blurs less: the classical map is better under 0.5 mm than under 2 mm
    by = {(p["values"]["strips.layers.cover_mm"], p["wires"]): p for p in summary["points"]}
    assert (
        by[(0.5, 10)]["methods"]["intersection"]["pearson_r_mean"]
        > by[(2.0, 10)]["methods"]["intersection"]["pearson_r_mean"]
    )
    assert [r["wire_budget"] for r in summary["recommended"]] == [8, 10]
    assert "Recommended design per wire budget" in (out / "sweep.md").read_text()
    assert (out / "dask-report.html").is_file()
    # resume: nothing is recomputed, the summary is the same
    (out / "sweep.json").unlink()
    assert main(["sweep", "--config", str(config), "--out", str(out), "--workers", "2", "--no-report"]) == 0
    again = json.loads((out / "sweep.json").read_text())
    assert again["computed_now"] == 0 and again["points"] == summary["points"]


def test_saturated_frames_are_counted_not_fatal_and_lower_the_recommendation() -> None:
    import numpy as np

    from synth.dataset import simulate_shard
    from synth.scene import load_scene
    from tactile_learn.sweep import recommend
    from tactile_learn.tasks import get_task
    from tactile_learn.tasks.base import EvalData, readable_frames

    scene = load_scene("strips5")
    task = get_task("strips")
    arrays = simulate_shard(scene, 0, 0, 10)
    data = EvalData(inputs=arrays["readings"].copy(), truth={"pressure": arrays["pressure"]}, scene=scene)
    data.inputs[[2, 7], 0] = scene.sensor.readout.full_scale_v  # two frames reach the ADC's top
    kept, unreadable = readable_frames(task, data)
    assert len(kept) == 8 and unreadable["share"] == pytest.approx(0.2)
    assert "saturated" in unreadable["first_reason"]
    np.testing.assert_array_equal(kept.inputs, np.delete(data.inputs, [2, 7], axis=0))

    row = {"pearson_r_mean": 0.9, "latency_us_p50_b1": 1.0}
    clean = {
        "id": "a",
        "status": "ok",
        "wires": 8,
        "values": {"x": 1},
        "methods": {"m": {**row, "pearson_r_mean": 0.8}},
    }
    saturating = {
        "id": "b",
        "status": "ok",
        "wires": 8,
        "values": {"x": 2},
        "methods": {"m": row},
        "unreadable": unreadable,
    }
    (best,) = recommend([clean, saturating])  # 0.9 on 80 % of the frames loses to 0.8 on all of them
    assert best["point"] == "a" and best["pearson_r_effective"] == pytest.approx(0.8)


def test_a_layout_is_a_design_parameter(tmp_path: Path) -> None:
    """``strips.geometry.layout`` in a sweep point: the point's scene, wires and (classical) methods."""
    import dataclasses

    from tactile_learn.sweep import run_point

    path = tmp_path / "layouts.toml"
    path.write_text(
        SWEEP.format(train=0).replace("[budget]", '"strips.geometry.layout" = ["orthogonal", "two_ended"]\n[budget]')
    )
    config = load_sweep(path)
    points = sweep_points(config)
    assert len(points) == 8
    values = {**points[0], "strips.geometry.layout": "two_ended"}
    assert wire_count(point_scene(config.base, values)) == 2 * (4 + 4)  # both ends of 4 + 4 strips
    budget = {
        **dataclasses.asdict(dataclasses.replace(config.budget, test=32)),
        "methods": ["intersection", "projection"],
    }
    result = run_point(values, config.base.to_dict(), budget, 0, str(tmp_path / "point"))
    assert result["status"] == "ok", result.get("error")
    assert result["wires"] == 16 and set(result["methods"]) == {"intersection", "projection"}


def test_rank_by_an_error_in_mm_and_bad_rank_by(tmp_path: Path) -> None:
    from tactile_learn.sweep import recommend

    def point(pid: str, wires: int, r: float, err: float) -> dict[str, object]:
        row = {"pearson_r_mean": r, "peak_err_mm_median": err, "nrmse": 0.5, "latency_us_p50_b1": 1.0}
        return {"id": pid, "status": "ok", "wires": wires, "values": {"n": wires}, "methods": {"m": row}}

    points = [point("coarse", 16, 0.87, 0.50), point("fine", 32, 0.83, 0.30)]
    assert [rec["point"] for rec in recommend(points)] == ["coarse", "coarse"]  # r favours the coarse array
    by_mm = recommend(points, "peak_err_mm_median")
    assert [rec["point"] for rec in by_mm] == ["coarse", "fine"]  # lower error wins once its wires fit
    path = tmp_path / "ranked.toml"
    path.write_text('rank_by = "peak_err_mm_median"\n' + SWEEP.format(train=0))
    assert load_sweep(path).rank_by == "peak_err_mm_median"
    path.write_text('rank_by = "speed"\n' + SWEEP.format(train=0))
    with pytest.raises(ConfigError, match="rank_by: 'speed' is not one of"):
        load_sweep(path)
