"""tactile-learn cards: shipped models' cards, their held-out metrics re-measured."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path
from typing import Any

from synth.errors import ConfigError
from synth.io import atomic_write_json
from tactile_learn.cli.common import non_negative_float, positive_int

HELP = "model cards: add held-out metrics to a card, or re-verify every card's metrics"
EXAMPLES = """\
  tactile-learn cards verify                                   # every model in models/
  tactile-learn cards verify --model strips5 --json results/cards_verify.json
  tactile-learn cards verify --model models/strips16.onnx --set two_spheres
  tactile-learn cards add --model models/strips16.onnx --name two_spheres --data data/strips16-test
  tactile-learn cards add --model models/strips16.onnx --name strips16_ood --suite strips16_ood
verify regenerates every held-out set a card names (scene, seed, n: generation is deterministic),
evaluates the model on it, and prints recorded vs now for each figure that moved; exit 1 if any
figure differs by more than --rtol (relative). add measures the model on a dataset folder or a suite
and records the metrics under metrics.NAME with the command and what regenerates the data."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=["verify", "add"], help="what to do with the cards")
    parser.add_argument(
        "--model",
        action="append",
        default=None,
        help="a shipped model's name or a .onnx path (repeatable; default: every model in models/)",
    )
    parser.add_argument("--set", action="append", default=None, dest="sets", help="verify: only these entries")
    parser.add_argument("--name", default=None, help="add: the entry's key under the card's metrics")
    parser.add_argument("--data", default=None, help="add: a held-out dataset folder")
    parser.add_argument("--suite", default=None, help="add: a suite name or file (metrics per family)")
    parser.add_argument("--n", type=positive_int, default=None, help="add --suite: frames per family")
    parser.add_argument(
        "--rtol",
        type=non_negative_float,
        default=None,
        help="relative tolerance (default: 1e-6, float32 rounding; 0: bit-exact)",
    )
    parser.add_argument("--json", default=None, help="write the full comparison here")
    parser.add_argument("--workdir", default=None, help="generate the held-out sets here (default: a temp folder)")


def _models(specs: list[str] | None) -> list[Path]:
    from tactile_learn.methods import model_dirs

    if not specs:
        folder = next((d for d in model_dirs() if d.is_dir() and any(d.glob("*.onnx"))), None)
        if folder is None:
            raise ConfigError("cards verify: no models/ folder with .onnx models found")
        return sorted(folder.glob("*.onnx"))
    paths = []
    for spec in specs:
        path = Path(spec)
        if path.suffix != ".onnx":
            found = [d / f"{spec}.onnx" for d in model_dirs() if (d / f"{spec}.onnx").is_file()]
            if not found:
                raise ConfigError(f"--model: no shipped model {spec!r} (give a name in models/ or a .onnx path)")
            path = found[0]
        paths.append(path)
    return paths


def _print(report: dict[str, Any]) -> None:
    for name, result in report["sets"].items():
        if result.get("error"):
            print(f"{report['model']} {name}: FAIL ({result['error']})")
            continue
        verdict = "pass" if result["ok"] else f"FAIL ({result['n_differ']} differ)"
        print(
            f"{report['model']} {name}: {result['n_checked']} figures, {result['n_exact']} exact, "
            f"{result['n_close']} within rtol {report['rtol']:g}: {verdict}"
        )
        for row in result["differ"][:20]:
            print(f"    {row['key']}: recorded {row['recorded']!r}, now {row['now']!r}")
        if result["n_differ"] > 20:
            print(f"    ... {result['n_differ'] - 20} more in the JSON")


def _add(args: argparse.Namespace) -> int:
    from tactile_learn.cards import add_metrics
    from tactile_learn.provenance import portable_path
    from tactile_learn.runtime import read_card
    from tactile_learn.tasks import get_task

    if not args.model or len(args.model) != 1 or not args.name:
        raise ConfigError("cards add: give one --model and the entry's --name")
    model = _models(args.model)[0]
    source = ["--data", portable_path(args.data)] if args.data else ["--suite", str(args.suite)]
    size = ["--n", str(args.n)] if args.n else []
    recipe = ["tactile-learn", "cards", "add", "--model", portable_path(model), "--name", args.name, *source, *size]
    entry = add_metrics(model, args.name, data=args.data, suite=args.suite, n=args.n, command=shlex.join(recipe))
    primary = get_task(read_card(model)["task"]).primary_metric[0]
    values = entry.get("values") or entry["mean_over_families"]
    print(f"{model}: metrics.{args.name}.{primary} = {values[primary]:.4f}")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.action == "add":
        return _add(args)
    from tactile_learn.cards import RTOL, verify_card

    reports = []
    for model in _models(args.model):
        report = verify_card(
            model,
            names=args.sets,
            rtol=RTOL if args.rtol is None else args.rtol,
            workdir=args.workdir,
            progress=lambda line: print(line, file=sys.stderr, flush=True),
        )
        _print(report)
        reports.append(report)
        if args.json:  # after every model: a long run that is stopped keeps what it measured
            atomic_write_json(args.json, {"ok": all(r["ok"] for r in reports), "models": reports})
    return 0 if all(r["ok"] for r in reports) else 1
