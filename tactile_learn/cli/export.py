"""tactile-learn export: a finished run to ONNX + model card, with a parity check."""

from __future__ import annotations

import argparse

from synth.io import json_dumps

HELP = "export a trained run to ONNX (parity-checked) with its model card"
EXAMPLES = """\
  tactile-learn export runs/s16-small --out models/strips16.onnx --test data/s16-test
  tactile-learn export runs/th --out models/thermal.onnx
Writes NAME.onnx and NAME.json (the card: inputs/outputs, normalisation, scene, training data and
metrics; with --test, held-out metrics of the exported ONNX model and the command that measured them)."""


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


def run(args: argparse.Namespace) -> int:
    from tactile_learn.export import export

    card = export(args.run, args.out, name=args.name, test=args.test, calibration=args.calibration)
    summary = {
        "model": args.out,
        "bytes": card["model_bytes"],
        "parity": card["parity"],
        "metrics": card["metrics"].get("heldout", {}).get("values", card["metrics"]["validation"]),
    }
    print(json_dumps(summary))
    return 0
