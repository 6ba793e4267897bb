"""scripts/speed_report.py: issue 15's benchmark files read together, every floor checked."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import speed_report


def _overhead_row(b1: float, b1024: float) -> dict[str, float]:
    return {"b1_us": b1, "b1024_us_per_frame": b1024, "overhead_ratio": b1 / b1024}


def _files(tmp_path: Path) -> dict[str, Any]:
    simulator = {
        "results": [
            {
                "scene": "thermal",
                "touches_per_s_wall": {"reference": 100.0, "fast": 950.0, "training": 4000.0},
                "speedup_wall": 9.5,
                "training_speedup_wall": 40.0,
            }
        ]
    }
    overhead = {
        "tasks": {
            "fsr": {
                "slow_method": _overhead_row(40.0, 4.0),
                "slow_method [stream]": _overhead_row(36.0, 4.0),
                "fast_method": _overhead_row(10.0, 5.0),
            }
        },
        "gating": [
            {
                "model": "fsr",
                "skipped_share": 0.8,
                "frames_per_s": {"ungated b1": 1000.0, "gated b1": 2500.0},
                "speedup_b1": 2.5,
                "speedup_b1024": 3.5,
            }
        ],
        "skins": {
            "quality": {"16x16 strips16": {"pearson_r_mean": 0.92}, "128x128 skin": {"pearson_r_mean": 0.89}},
            "b1_us": {"16x16 strips16": 100.0, "128x128 skin": 250.0},
            "latency_ratio_128_over_16": 2.5,
            "r_difference_128_minus_16": -0.03,
        },
    }
    ood = {"ood_mean": {"pearson_r_mean": 0.8, "nrmse": 0.5}, "two_spheres": {"pearson_r_mean": 0.9}}
    pareto = {
        "methods": {"fast_net": {**ood, "latency": {"predict_median_us": 90.0}}},
        "pareto_front": {"two_spheres": ["fast_net"]},
    }
    paths = {}
    for name, data in (("simulator", simulator), ("overhead", overhead), ("pareto", pareto)):
        paths[name] = tmp_path / f"{name}.json"
        paths[name].write_text(json.dumps(data))
    return paths


def test_each_floor_is_marked_from_its_own_figures(tmp_path: Path) -> None:
    paths = _files(tmp_path)
    out = tmp_path / "speed.md"
    argv = [f"--{k}={v}" for k, v in paths.items()] + ["--out", str(out)]
    assert speed_report.main(argv) == 0
    lines = out.read_text().splitlines()

    def row(start: str) -> str:
        return next(line for line in lines if line.startswith(start))

    assert "whole record **not met**, stream met" in row("| thermal |")
    assert row("| fsr | slow_method |").endswith("**not met** |")  # 9x even on the stream path
    assert row("| fsr | fast_method |").endswith("| met |")  # 2x
    assert "**not met**" in row("| fsr | 80.0 % |")  # gating 2.5x < 3x
    skin = row("latency ratio")
    assert "2.50x (met)" in skin and "-0.030 (**not met**" in skin
    assert row("| fast_net |").endswith("| yes |")


def test_a_missing_benchmark_file_is_named_and_nothing_is_written(tmp_path: Path, capsys: Any) -> None:
    paths = _files(tmp_path)
    paths["pareto"].unlink()
    out = tmp_path / "speed.md"
    argv = [f"--{k}={v}" for k, v in paths.items()] + ["--out", str(out)]
    assert speed_report.main(argv) == 2
    assert "pareto.json is missing" in capsys.readouterr().err
    assert not out.exists()
