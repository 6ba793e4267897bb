"""tactile-learn sweep: design points (generate x train x evaluate) on a Dask cluster."""

from __future__ import annotations

import argparse
from typing import Any

from tactile_learn.cli.common import positive_int

HELP = "sweep sensor designs (strips per side, pitch, cover, noise, ADC bits, ...) on a Dask cluster"
EXAMPLES = """\
  tactile-learn sweep --config strips_design --out runs/sweep              # a local 2-worker cluster
  tactile-learn sweep --config my_sweep.toml --out runs/sweep --workers 4
  tactile-learn sweep --config my_sweep.toml --out runs/sweep --scheduler tcp://10.0.0.5:8786
  tactile-learn sweep --config my_sweep.toml --out runs/sweep --list      # the points, nothing run
A sweep file names a base scene, the parameters to vary (dotted scene paths), the search (grid or
random) and a per-point budget; see tactile_learn/sweeps/strips_design.toml. Rerunning the same
command resumes: finished points (OUT/points/ID/result.json) are not recomputed. Writes
OUT/sweep.json (every point's config and metrics), OUT/sweep.md (the table and the recommended design
per wire budget), OUT/sweep.png (error against wire count and latency) and OUT/dask-report.html
(Dask's performance report of the run)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", required=True, help="sweep .toml (or the name of a shipped sweep)")
    parser.add_argument("--out", required=True, help="output folder (resumable)")
    parser.add_argument("--workers", type=positive_int, default=2, help="local cluster worker processes (default 2)")
    parser.add_argument("--scheduler", default=None, help="address of a running Dask scheduler instead")
    parser.add_argument("--list", action="store_true", help="print the design points and stop")
    parser.add_argument("--no-report", action="store_true", help="skip Dask's HTML performance report")


def run(args: argparse.Namespace) -> int:
    from tactile_learn.sweep import load_sweep, point_id, run_sweep, sweep_points

    config = load_sweep(args.config)
    points = sweep_points(config)
    if args.list:
        for values in points:
            print(point_id(values), values)
        print(f"{len(points)} points")
        return 0

    def report(result: dict[str, Any]) -> None:
        status = "ok" if result.get("status") == "ok" else f"FAILED ({result.get('error')})"
        print(f"point {result['id']} {result['values']}: {status} in {result['seconds']:.0f} s", flush=True)

    summary = run_sweep(
        config, args.out, scheduler=args.scheduler, workers=args.workers, report=not args.no_report, progress=report
    )
    failed = [p for p in summary["points"] if p.get("status") != "ok"]
    print(
        f"{len(summary['points'])} of {summary['n_points']} points done ({summary['computed_now']} now, "
        f"{len(failed)} failed) in {summary['seconds']:.0f} s; results in {args.out}/sweep.md"
    )
    return 1 if failed else 0
