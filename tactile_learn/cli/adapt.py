"""tactile-learn adapt: a classifier for your own thermal sensor from a handful of labelled touches."""

from __future__ import annotations

import argparse

from synth.io import json_dumps
from synth.materials import load_class_map
from tactile_learn.cli.common import positive_int

HELP = "calibrate a real thermal sensor from labelled touches, train a classifier for it, export ONNX"
EXAMPLES = """\
  tactile-learn adapt --task thermal --data my_touches/ --channels all --out adapted/
  tactile-learn adapt --task thermal --data my_touches/ --channels heated --classes my_classes.toml --out adapted/
  tactile-learn eval --task thermal --data more_touches/ --method adapted/ --group-by condition
my_touches/ holds touches.csv (file,material[,onset_s][,...]) and one CSV per touch
(time_s,temperature_c[,passive_c][,force]); labels are materials, families (metal, wood, ...) or
your classes (--classes FILE.toml, see 'tactile-learn materials --help'). --channels heated: the
classifier reads the heated thermistor only; all: heated and passive. The output folder holds the
calibrated scene (sensor.toml), the calibration report (calibration.json), the synthetic datasets,
the training run, model.onnx with its card (model.json) and a copy of the labelled touches
(labelled/). What you classify with is adapt's choice (eval --method adapted/): per duration of
contact, the network, the calibrated model and two classifiers trained on your labelled touches
alone are scored on those touches, and those within one touch of the best vote (the card's
'classifier'); adapted/model.onnx is the network alone."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", required=True, choices=["thermal"])
    parser.add_argument("--data", required=True, help="labelled recordings folder")
    parser.add_argument("--out", required=True, help="output folder (must be new or empty)")
    parser.add_argument("--channels", default="all", choices=["heated", "all"], help="classifier inputs (default all)")
    parser.add_argument("--classes", default=None, help="TOML file mapping your class names to materials/families")
    parser.add_argument("--n-train", type=positive_int, default=16000, help="synthetic training touches")
    parser.add_argument("--epochs", type=positive_int, default=12)
    parser.add_argument("--starts", type=positive_int, default=6, help="calibration multi-start count (default 6)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=positive_int, default=1, help="torch threads (default 1)")
    parser.add_argument("--workers", type=positive_int, default=1, help="generation processes")


def run(args: argparse.Namespace) -> int:
    import sys

    from tactile_learn.thermal_adapt import adapt

    class_map = load_class_map(args.classes) if args.classes else None
    card = adapt(
        args.data,
        args.out,
        channels=args.channels,
        class_map=class_map,
        n_train=args.n_train,
        epochs=args.epochs,
        seed=args.seed,
        starts=args.starts,
        threads=args.threads,
        workers=args.workers,
    )
    summary = {
        "model": f"{args.out}/model.onnx",
        "classes": card["classes"],
        "channels": card["channels"],
        "calibration_residual": card["calibration"]["residual"],
        "labelled_touches_accuracy_by_duration": card["metrics"]["labelled_touches"]["values"]["accuracy_by_duration"],
        "classifier_by_duration": {
            d: {"members": c["members"], "best_score": max(c["scores"].values())}
            for d, c in card["classifier"]["by_duration"].items()
        },
        "classify_with": f"tactile-learn eval --task thermal --method {args.out} --data YOUR_TOUCHES",
        "timings_s": card["adapt"]["timings_s"],
    }
    print(json_dumps(summary))
    for warning in card["warnings"]:
        print(f"tactile-learn adapt: warning: {warning}", file=sys.stderr)
    return 0
