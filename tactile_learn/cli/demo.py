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
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    _step("shipped scenes")
    _cli(["scenes"])
    _step("strip array: the paper's figures with the classical estimators")
    _classical_figures(out)
    if not args.skip_train:
        _step("train a quick strips16 model on CPU, export it to ONNX, evaluate it under onnxruntime")
        _quick_model(out, args.train_n)
    _step("benchmark every task: shipped models against the classical algorithms")
    _cli(["bench", "--task", "all", "--quick", "--json", str(out / "bench.json"), "--plot", str(out / "bench.png")])
    print(
        f"\ndemo finished in {time.perf_counter() - started:.0f} s; "
        f"tables and plots are in {out}/ (bench.md, bench.png)"
    )
    return 0


def _generate(scene: str, n: int, seed: int, folder: Path, *extra: str) -> None:
    _cli(["generate", "--scene", scene, "--n", str(n), "--seed", str(seed), "--out", str(folder), *extra, "--quiet"])


def _classical_figures(out: Path) -> None:
    """Held-out frames of both strip scenes and the classical estimators' metrics on them."""
    for scene in ("strips16", "strips5"):
        data = out / f"{scene}-test"
        _generate(scene, 1000, 77, data)
        for method in ("intersection", "projection"):
            json_out = str(out / f"eval-{scene}-{method}.json")
            _cli(["eval", "--task", "strips", "--data", str(data), "--method", method, "--json", json_out])


def _quick_model(out: Path, train_n: int) -> None:
    """A quick strips16 model (3 epochs, resumed if a run is there), exported, evaluated beside the
    shipped one on the held-out frames of :func:`_classical_figures`."""
    train, val, test = out / "strips16-train", out / "strips16-val", out / "strips16-test"
    _generate("strips16", train_n, 1, train, "--workers", "2")
    _generate("strips16", 1000, 2, val)
    run_dir = out / "run-strips16"
    resume = ["--resume"] if (run_dir / "checkpoint.pt").exists() else []
    recipe = ["--epochs", "3", "--quiet", *resume]
    _cli(["train", "--task", "strips", "--data", str(train), "--val", str(val), "--out", str(run_dir), *recipe])
    model = out / "strips16-demo.onnx"
    _cli(["export", str(run_dir), "--out", str(model), "--test", str(test), "--overwrite"])  # a rerun's own model
    # the quick model, then the shipped one for comparison
    for method in (str(model), "strips16"):
        _cli(["eval", "--task", "strips", "--data", str(test), "--method", method, "--summary"])
