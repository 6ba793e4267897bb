"""tactile-learn demo: the whole pipeline in minutes, on shipped defaults."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from tactile_learn.cli.common import positive_int

HELP = "run the main job end to end: simulate, classical baselines, train, export, benchmark"
EXAMPLES = """\
  tactile-learn demo                 # writes demo-out/ (tables, plots, a freshly trained model)
  tactile-learn demo --out demo-quick --skip-train"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="demo-out", help="folder for the demo's data, model, tables and plots")
    parser.add_argument("--train-n", type=positive_int, default=20000, help="training frames for the quick model")
    parser.add_argument("--skip-train", action="store_true", help="only benchmark the shipped models")


def _step(title: str) -> float:
    print(f"\n=== {title} ===", flush=True)
    return time.perf_counter()


def _cli(argv: list[str]) -> None:
    """Run one subcommand; a failing step ends the demo with that step's error."""
    from synth.errors import TactileError
    from tactile_learn.cli import main

    code = main(argv)
    if code != 0:
        raise TactileError(f"demo step 'tactile-learn {' '.join(argv)}' failed (exit {code})")


def run(args: argparse.Namespace) -> int:
    cli = _cli
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    _step("shipped scenes")
    cli(["scenes"])

    _step("strip array: the paper's figures with the classical estimators")
    for scene in ("strips16", "strips5"):
        data = out / f"{scene}-test"
        cli(["generate", "--scene", scene, "--n", "1000", "--seed", "77", "--out", str(data), "--quiet"])
        for method in ("intersection", "projection"):
            cli(
                [
                    "eval",
                    "--task",
                    "strips",
                    "--data",
                    str(data),
                    "--method",
                    method,
                    "--json",
                    str(out / f"eval-{scene}-{method}.json"),
                ]
            )

    if not args.skip_train:
        _step("train a quick strips16 model on CPU, export it to ONNX, evaluate it under onnxruntime")
        train, val = out / "strips16-train", out / "strips16-val"
        cli(
            [
                "generate",
                "--scene",
                "strips16",
                "--n",
                str(args.train_n),
                "--seed",
                "1",
                "--out",
                str(train),
                "--workers",
                "2",
                "--quiet",
            ]
        )
        cli(["generate", "--scene", "strips16", "--n", "1000", "--seed", "2", "--out", str(val), "--quiet"])
        run_dir = out / "run-strips16"
        resume = ["--resume"] if (run_dir / "checkpoint.pt").exists() else []
        cli(
            [
                "train",
                "--task",
                "strips",
                "--data",
                str(train),
                "--val",
                str(val),
                "--out",
                str(run_dir),
                "--epochs",
                "3",
                "--quiet",
                *resume,
            ]
        )
        model = out / "strips16-demo.onnx"
        cli(["export", str(run_dir), "--out", str(model), "--test", str(out / "strips16-test")])
        cli(["eval", "--task", "strips", "--data", str(out / "strips16-test"), "--method", str(model), "--summary"])
        cli(
            [
                "eval",
                "--task",
                "strips",
                "--data",
                str(out / "strips16-test"),
                "--method",
                "strips16",  # the shipped model, for comparison with the quick one
                "--summary",
            ]
        )

    _step("benchmark every task: shipped models against the classical algorithms")
    cli(
        [
            "bench",
            "--task",
            "all",
            "--quick",
            "--json",
            str(out / "bench.json"),
            "--plot",
            str(out / "bench.png"),
        ]
    )
    print(
        f"\ndemo finished in {time.perf_counter() - started:.0f} s; "
        f"tables and plots are in {out}/ (bench.md, bench.png)"
    )
    return 0
