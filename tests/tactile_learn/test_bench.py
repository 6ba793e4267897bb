"""The benchmark harness itself: schema, sensitivity to speed, agreement with eval."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest

from synth.dataset import generate
from synth.scene import Scene, load_scene
from tactile_learn.bench import bench_task
from tactile_learn.bench_report import markdown, pareto_plot
from tactile_learn.cli import main
from tactile_learn.estimators.classical.intersection import IntersectionEstimator
from tactile_learn.tasks.strips import StripsTask
from tactile_learn.timing import time_predict


class SlowIntersection(IntersectionEstimator):
    name = "slow_intersection"

    def predict(self, X: np.ndarray) -> np.ndarray:
        time.sleep(0.004)
        return super().predict(X)


@pytest.fixture()
def with_slow_method(monkeypatch: pytest.MonkeyPatch) -> None:
    original = StripsTask.classical_methods

    def methods(self: StripsTask) -> dict:
        return {**original(self), "slow_intersection": SlowIntersection}

    monkeypatch.setattr(StripsTask, "classical_methods", methods)


def test_schema_and_a_slowed_method_measures_slower(with_slow_method: None, workdir: Path) -> None:
    result = bench_task("strips", n_frames=40, repeats=30, budget_s=0.3, scene_name="strips5")
    assert {"task", "scene", "n_frames", "machine", "methods", "ratios"} <= set(result)
    assert result["task"] == "strips" and result["n_frames"] == 40
    assert {"cpu", "cores", "versions"} <= set(result["machine"])
    by_name = {m["name"]: m for m in result["methods"]}
    assert {"intersection", "projection", "slow_intersection"} <= set(by_name)
    for m in result["methods"]:
        assert {
            "name",
            "kind",
            "backend",
            "metrics",
            "latency_us_p50_b1",
            "latency_us_p99_b1",
            "throughput_fps_b1024",
        } <= set(m)
        assert m["kind"] in ("classical", "learned")
        assert m["latency_us_p99_b1"] >= m["latency_us_p50_b1"] > 0 and m["throughput_fps_b1024"] > 0
        assert {"pearson_r_mean", "pearson_r_median", "nrmse"} <= set(m["metrics"])
    fast, slow = by_name["intersection"], by_name["slow_intersection"]
    # the sleep adds 4 ms per call: far beyond any jitter of a ~0.1 ms method
    assert slow["latency_us_p50_b1"] > fast["latency_us_p50_b1"] + 3000
    assert slow["metrics"]["nrmse"] == pytest.approx(fast["metrics"]["nrmse"])
    ratios = result["ratios"]
    assert ratios["reference"] == "intersection" and ratios["error_metric"] == "nrmse"
    errors = {m["name"]: m["metrics"]["nrmse"] for m in result["methods"] if m["kind"] == "classical"}
    assert ratios["best_classical"] == min(errors, key=errors.__getitem__)
    assert any(m["kind"] == "learned" for m in result["methods"]), "the shipped strips5 model is benchmarked"
    for name, m in by_name.items():
        entry = ratios.get(f"{name} [{m['backend']}]")
        if m["kind"] == "learned":  # the shipped strips5 model
            assert entry["error_ratio"] == pytest.approx(m["metrics"]["nrmse"] / errors["intersection"])
            # the most accurate classical method is at least as accurate as the paper's
            assert entry["error_ratio_best"] >= entry["error_ratio"]
    json.dumps(result, allow_nan=True)
    table = markdown(result)
    assert "slow_intersection" in table and "p50 us" in table
    assert pareto_plot([result], workdir / "p.png") and (workdir / "p.png").stat().st_size > 1000


def test_time_predict_counts_what_it_times() -> None:
    calls: list[int] = []

    def predict(x: np.ndarray) -> None:
        calls.append(len(x))

    timing = time_predict(predict, np.zeros((5, 3), np.float32), repeats=20, budget_s=0.1, warmup=2)
    assert timing["latency_samples"] == 20
    assert calls.count(1) == 22 and calls.count(1024) >= 4


def test_bench_metrics_equal_eval_metrics(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene: Scene = load_scene("strips5")
    generate(scene, 120, 8, "frames", shard_size=64)
    result = bench_task("strips", n_frames=120, repeats=10, budget_s=0.1, data="frames", methods=["projection"])
    assert [m["name"] for m in result["methods"]] == ["projection"]
    assert main(["eval", "--task", "strips", "--data", "frames", "--method", "projection", "--json", "e.json"]) == 0
    evaluated = json.loads(Path("e.json").read_text())["metrics"]
    benched = result["methods"][0]["metrics"]
    for key in ("pearson_r_mean", "pearson_r_median", "nrmse", "peak_err_mm_median"):
        assert benched[key] == pytest.approx(evaluated[key], rel=1e-9)
    capsys.readouterr()


def test_bench_cli_writes_json_table_and_plot(workdir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(
        [
            "bench",
            "--task",
            "strips",
            "--scene",
            "strips5",
            "--quick",
            "--n",
            "50",
            "--method",
            "intersection",
            "--json",
            "b.json",
            "--plot",
            "b.png",
        ]
    )
    assert code == 0
    data = json.loads(Path("b.json").read_text())
    assert data["task"] == "strips" and data["methods"][0]["name"] == "intersection"
    assert Path("b.md").read_text().startswith("**strips**")
    assert Path("b.png").exists()
    assert "| intersection |" in capsys.readouterr().out


def test_a_routed_cards_torch_row_is_labelled_as_its_own_graph() -> None:
    """The torch weights beside a routed card are its own network's: the benchmark must not present
    them as the routed model."""
    pytest.importorskip("torch")
    from tactile_learn.bench import _learned_variants
    from tactile_learn.runtime import read_card
    from tests.paths import REPO_ROOT

    assert "route" in read_card(REPO_ROOT / "models" / "strips16.onnx")  # (the shipped default routes since stop 32)
    labels = [label for label, _ in _learned_variants("strips", load_scene("strips16"))]
    assert labels.count("strips16") == 2  # onnxruntime, 1 and 2 threads: the routed model
    assert "strips16 (own graph)" in labels and "strips16_small" in labels
    assert "strips16_small (own graph)" not in labels  # unrouted cards keep their name
