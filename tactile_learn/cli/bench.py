"""tactile-learn bench: run time against error for every method and backend."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from synth.errors import ConfigError
from synth.io import atomic_write_json, atomic_write_text
from tactile_learn.cli.common import positive_int

HELP = "benchmark every method and backend of a task: error, latency (b1) and throughput (b1024)"
EXAMPLES = """\
  tactile-learn bench --task strips --json results/strips.json --plot results/strips.png
  tactile-learn bench --task all --quick
  tactile-learn bench --task simulator
  tactile-learn bench --task fsr --data data/fsr-test --n 5000
  tactile-learn bench --task strips --suite strips16_ood --json results/strips_ood.json
Learned methods are the shipped models of the task (models/*.onnx whose scene matches), run with
onnxruntime on 1 and 2 threads and, when torch and NAME.pt are present, torch eager. The JSON schema
is documented in tactile_learn/bench.py; a Markdown table is printed and written beside the JSON."""

TASKS = ("strips", "thermal", "fsr", "capacitive", "simulator", "all")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", required=True, choices=TASKS)
    parser.add_argument("--json", default=None, help="write results here (and a .md table beside it)")
    parser.add_argument("--plot", default=None, help="Pareto plot (PNG): error against latency")
    parser.add_argument("--quick", action="store_true", help="fewer frames and repeats (a minute per task)")
    parser.add_argument("--n", type=positive_int, default=None, help="held-out frames (default 2000, quick 500)")
    parser.add_argument("--data", default=None, help="evaluate on this dataset instead of fresh frames")
    parser.add_argument("--scene", default=None, help="scene (default: the task's)")
    parser.add_argument("--method", action="append", default=None, help="only these methods (repeatable)")
    parser.add_argument("--reference", action="store_true", help="add reference metrics (thermal: the oracle; slow)")
    parser.add_argument("--suite", default=None, help="per-family results on a suite (e.g. strips16_ood)")


def run(args: argparse.Namespace) -> int:
    from tactile_learn.bench import bench_simulator, bench_task
    from tactile_learn.bench_report import markdown, pareto_plot

    tasks = ["strips", "thermal", "fsr", "capacitive", "simulator"] if args.task == "all" else [args.task]
    _check_methods(args.method, [args.task] if args.suite else tasks)
    if args.suite:
        return _run_suite(args)
    results: list[dict[str, Any]] = []
    for task in tasks:
        if task == "simulator":
            result = bench_simulator(quick=args.quick)
        else:
            from tactile_learn.tasks import get_task

            default_n = get_task(task).bench_samples
            result = bench_task(
                task,
                n_frames=args.n or (max(1, default_n // 4) if args.quick else default_n),
                reference=args.reference,
                repeats=100 if args.quick else 400,
                budget_s=1.0 if args.quick else 4.0,
                scene_name=args.scene,
                data=args.data,
                methods=args.method,
                progress=lambda text: print(f"  measuring {text}", file=sys.stderr, flush=True),
            )
        results.append(result)
        print(markdown(result), flush=True)
    payload: dict[str, Any] = results[0] if len(results) == 1 else {"task": "all", "results": results}
    if args.json:
        atomic_write_json(args.json, payload)
        atomic_write_text(Path(args.json).with_suffix(".md"), "\n".join(markdown(r) for r in results))
    if args.plot:
        pareto_plot(results, args.plot)
    return 0


def _check_methods(names: list[str] | None, tasks: list[str]) -> None:
    """Every ``--method`` is a method of one of ``tasks`` (an unknown name gave an empty table)."""
    from tactile_learn.methods import available_methods

    known = [m for task in tasks if task not in ("simulator", "all") for m in available_methods(task)]
    unknown = [name for name in names or () if name not in known]
    if unknown:
        raise ConfigError(
            f"--method: {unknown[0]!r} is not a method of {' or '.join(tasks)} (available: {', '.join(known)})"
        )


def _run_suite(args: argparse.Namespace) -> int:
    from tactile_learn.bench import bench_suite
    from tactile_learn.bench_report import suite_markdown

    if args.task not in ("strips", "thermal", "fsr"):
        raise ConfigError(f"--suite: needs one task (strips, thermal or fsr), not {args.task!r}")
    result = bench_suite(
        args.task,
        args.suite,
        n_frames=args.n,
        repeats=100 if args.quick else 400,
        budget_s=1.0 if args.quick else 4.0,
        methods=args.method,
        progress=lambda text: print(f"  measuring {text}", file=sys.stderr, flush=True),
    )
    print(suite_markdown(result), flush=True)
    if args.json:
        atomic_write_json(args.json, result)
        atomic_write_text(Path(args.json).with_suffix(".md"), suite_markdown(result))
    return 0
