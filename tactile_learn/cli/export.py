"""tactile-learn export: a finished run to ONNX + model card, with a parity check."""

from __future__ import annotations

import argparse
from pathlib import Path

from synth.errors import ConfigError
from synth.io import json_dumps

HELP = "export a trained run to ONNX (parity-checked) with its model card"
EXAMPLES = """\
  tactile-learn export runs/s16-small --out models/my_strips16.onnx --test data/s16-test
  tactile-learn export runs/th --out models/my_thermal.onnx
  tactile-learn export runs/s16-small --out models/my_strips16.onnx --test data/s16-test --overwrite
Writes NAME.onnx and NAME.json (the card: inputs/outputs, normalisation, scene, training data and
metrics; with --test, held-out metrics of the exported ONNX model and the command that measured them)
and NAME.pt (the torch weights). A model already at --out (e.g. a shipped one) is kept unless --overwrite."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run", help="run folder written by 'tactile-learn train'")
    parser.add_argument("--out", required=True, help="output .onnx path (the card goes beside it)")
    parser.add_argument("--test", default=None, help="held-out dataset to measure the card's metrics on")
    parser.add_argument("--name", default=None, help="model name in the card (default: the file's stem)")
    parser.add_argument(
        "--calibration",
        default=None,
        help="frames that calibrate card entries such as the strips flag thresholds (default: run validation set)",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace a model (.onnx, .json, .pt) at --out")


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    existing = [p.name for p in (out, out.with_suffix(".json"), out.with_suffix(".pt")) if p.exists()]
    if existing and not args.overwrite:  # following an example must not replace a shipped model
        raise ConfigError(f"--out: {out} would replace {', '.join(existing)}; choose another --out or pass --overwrite")
    from tactile_learn.export import export  # torch: imported only once the export will run

    card = export(args.run, args.out, name=args.name, test=args.test, calibration=args.calibration)
    summary = {
        "model": args.out,
        "bytes": card["model_bytes"],
        "parity": card["parity"],
        "metrics": card["metrics"].get("heldout", {}).get("values", card["metrics"]["validation"]),
    }
    print(json_dumps(summary))
    return 0
