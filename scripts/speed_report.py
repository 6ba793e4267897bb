"""Issue 15's figures in one table: the speed benchmarks' JSON files read together, each floor checked.

``make bench-speed`` runs the three benchmarks one after the other (one run) and then this script:

- ``scripts/thermal_sim_speed.py``: thermal simulator touches/s, before (the whole-record reference
  path) and after (the fast path; the training stream), floor 10x;
- ``scripts/latency_overhead.py``: batch-1 latency and batch-1024 per-frame cost of every estimator
  (target ratio <= 3), gated streams with 80 % idle frames (floor 3x), the 128 x 128 skin against
  the 16 x 16 array (latency <= 3x, r within 0.02);
- ``scripts/strips_pareto.py``: the strips Pareto front (accuracy on two spheres and the OOD suite
  against batch-1 latency).

    python scripts/speed_report.py --out results/speed.md
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

SIMULATOR_FLOOR = 10.0
OVERHEAD_FLOOR = 3.0
GATING_FLOOR = 3.0
SKIN_LATENCY_FLOOR = 3.0
SKIN_R_TOLERANCE = 0.02


def _mark(ok: bool) -> str:
    return "met" if ok else "**not met**"


def simulator_section(data: dict[str, Any]) -> list[str]:
    lines = [
        "## Thermal simulator (touches/s, median of interleaved repeats)",
        "",
        f"`{data.get('command', '')}` (load {_load(data)})",
        "",
        "| scene | before (whole record) | after (whole record) | speed-up | training stream | speed-up | floor 10x |",
        "|---|---:|---:|---:|---:|---:|---|",
    ]
    for row in data["results"]:
        rates = row["touches_per_s_wall"]
        best = max(row["speedup_wall"], row["training_speedup_wall"])
        lines.append(
            f"| {row['scene']} | {rates['reference']:,.0f} | {rates['fast']:,.0f} | {row['speedup_wall']:.2f}x | "
            f"{rates['training']:,.0f} | {row['training_speedup_wall']:.2f}x | "
            f"whole record {_mark(row['speedup_wall'] >= SIMULATOR_FLOOR)}, "
            f"stream {_mark(best >= SIMULATOR_FLOOR)} |"
        )
    return lines


def _median_call(row: dict[str, Any]) -> str:
    """The median single call, where the run recorded it (runs before it was added did not)."""
    return f"{row['b1_median_us']:,.1f}" if "b1_median_us" in row else "-"


def overhead_section(data: dict[str, Any]) -> list[str]:
    lines = [
        "## Per-frame overhead (us; medians of interleaved rounds)",
        "",
        "Batch 1: each frame's median call, averaged over the same frames the batch-1024 call holds (equal mix of",
        "frames with and without contact); the median single call beside it.",
        "",
        f"`{data.get('command', '')}` (load {_load(data)})",
        "",
        "| task | method | batch 1 | median call | batch 1024 per frame | ratio | stream batch 1 | stream ratio "
        "| <= 3x |",
        "|---|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    for task, methods in data.get("tasks", {}).items():
        for name, row in methods.items():
            if name.endswith("[stream]"):
                continue
            stream = methods.get(f"{name} [stream]")
            best = min(row["overhead_ratio"], stream["overhead_ratio"] if stream else float("inf"))
            stream_cells = f"{stream['b1_us']:,.1f} | {stream['overhead_ratio']:.1f}" if stream is not None else "- | -"
            lines.append(
                f"| {task} | {name} | {row['b1_us']:,.1f} | {_median_call(row)} | {row['b1024_us_per_frame']:,.2f} | "
                f"{row['overhead_ratio']:.1f} | {stream_cells} | {_mark(best <= OVERHEAD_FLOOR)} |"
            )
    return lines


def gating_section(data: dict[str, Any]) -> list[str]:
    rows = data.get("gating", [])
    if not rows:
        return []
    lines = [
        "## Gated streams (80 % idle frames; frames/s)",
        "",
        "| model | skipped | ungated b1 | gated b1 | speed-up b1 | speed-up b1024 | floor 3x (b1) |",
        "|---|---:|---:|---:|---:|---:|---|",
    ]
    for row in rows:
        fps = row["frames_per_s"]
        lines.append(
            f"| {row['model']} | {100 * row['skipped_share']:.1f} % | {fps['ungated b1']:,.0f} | "
            f"{fps['gated b1']:,.0f} | {row['speedup_b1']:.2f}x | {row['speedup_b1024']:.2f}x | "
            f"{_mark(row['speedup_b1'] >= GATING_FLOOR)} |"
        )
    return lines


def skins_section(data: dict[str, Any]) -> list[str]:
    skins = data.get("skins")
    if not skins:
        return []
    ratio, dr = skins["latency_ratio_128_over_16"], skins["r_difference_128_minus_16"]
    quality = skins["quality"]
    return [
        "## Large skin: 128 x 128 against 16 x 16, two contacts",
        "",
        "| array | r | batch-1 latency (us) |",
        "|---|---:|---:|",
        *(f"| {label} | {quality[label]['pearson_r_mean']:.3f} | {skins['b1_us'][label]:,.0f} |" for label in quality),
        "",
        f"latency ratio {ratio:.2f}x ({_mark(ratio <= SKIN_LATENCY_FLOOR)}), r difference {dr:+.3f} "
        f"({_mark(dr >= -SKIN_R_TOLERANCE)}: within 0.02 or better)",
    ]


def pareto_section(data: dict[str, Any]) -> list[str]:
    lines = [
        "## Strips: accuracy against batch-1 latency",
        "",
        f"`{data.get('command', '')}`",
        "",
        "| method | two spheres r | OOD mean r | OOD NRMSE | predict (us) | on the front |",
        "|---|---:|---:|---:|---:|---|",
    ]
    front = {name for names in data.get("pareto_front", {}).values() for name in names}
    for name, row in data["methods"].items():
        lines.append(
            f"| {name} | {row['two_spheres']['pearson_r_mean']:.3f} | {row['ood_mean']['pearson_r_mean']:.3f} | "
            f"{row['ood_mean']['nrmse']:.3f} | {row['latency']['predict_median_us']:,.0f} | "
            f"{'yes' if name in front else ''} |"
        )
    return lines


def _load(data: dict[str, Any]) -> str:
    load = data.get("load_average_1min")
    return " -> ".join(f"{x:.2f}" for x in load) if load else "?"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--simulator", default="results/thermal_sim_speed.json")
    parser.add_argument("--overhead", default="results/latency_overhead.json")
    parser.add_argument("--pareto", default="results/strips_pareto.json")
    parser.add_argument("--out", default="results/speed.md")
    args = parser.parse_args(argv)
    sections: list[str] = ["# Speed (issue 15), one benchmark run", ""]
    for path, build in (
        (args.simulator, simulator_section),
        (args.overhead, overhead_section),
        (args.overhead, gating_section),
        (args.overhead, skins_section),
        (args.pareto, pareto_section),
    ):
        if not Path(path).is_file():
            print(f"speed_report: {path} is missing (run its benchmark first, e.g. make bench-speed)", file=sys.stderr)
            return 2
        sections += [*build(json.loads(Path(path).read_text())), ""]
    from synth.io import atomic_write_text

    atomic_write_text(args.out, "\n".join(sections))
    print("\n".join(sections))
    return 0


if __name__ == "__main__":
    sys.exit(main())
