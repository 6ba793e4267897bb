"""tactile-learn eval: metrics of any method on anyone's frames."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from synth.dataset import MANIFEST
from synth.errors import ConfigError, DataError
from synth.io import atomic_write_json, json_dumps
from synth.scene import load_scene
from tactile_learn.cli.common import positive_int
from tactile_learn.few_shot import FEW_SHOT_METHODS, few_shot_evaluate
from tactile_learn.methods import model_scene, resolve_method
from tactile_learn.tasks import TASK_NAMES, get_task
from tactile_learn.thermal_choice import choice_evaluate, load_adapted

HELP = "evaluate a classical method or an ONNX model on a dataset, an .npz or recordings"
EXAMPLES = """\
  tactile-learn eval --task strips --data data/strips16-test --method intersection
  tactile-learn eval --task strips --data data/strips16-test --method models/strips16.onnx --json out.json
  tactile-learn eval --task strips --data data/strips16-test --method runs/s16    # a run, before export (torch)
  tactile-learn eval --task strips --data my_frames.npz --scene strips5 --method projection
  tactile-learn eval --task thermal --data my_touches/ --method curve_match
  tactile-learn eval --task strips --suite strips16_ood --method strips16 --json ood.json
  tactile-learn eval --task strips --data data/kitchen-test --method bundles/kitchen/bundle.json  # a bundle
  tactile-learn eval --task thermal --data robot/ --method adapted/ --durations 0.5,1,2,4 --group-by condition
  tactile-learn eval --task thermal --data robot/ --method adapted/model.onnx    # adapt's network alone
  tactile-learn eval --task thermal --data robot/ --method press_aligned --train labelled/ --scene adapted/sensor.toml
An .npz needs the task's arrays (strips: 'readings' (B, N+M) and 'pressure' (B, N, M)); a dataset
folder from 'generate' carries its own scene; other data is read with the model's scene (a
classical method: the task's default) unless --scene names one. Prints and writes
{"task", "method", "n_frames", "metrics": {...}}. With --suite (families of shapes, synth/suites/),
fresh frames of every family are simulated (--n per family, --seed) and the metrics are reported per
family and as their mean over families: {"suite", "families": {...}, "mean_over_families": {...}}.
The thermal few-shot methods (aligned_pca, press_aligned: docs/thermal-real.md) learn
from the labelled recordings in --train (one model per duration) and add their leave-one-out
accuracy on them (leave_one_out_by_duration). An adapt output folder as --method classifies with
the classifier adapt chose (its card's 'classifier': the network and the few-shot methods, scored
on the labelled touches adapt kept; those within one touch of the best vote; choice_by_duration)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", required=True, choices=TASK_NAMES)
    parser.add_argument("--data", default=None, help="dataset folder, .npz file, or recordings folder")
    parser.add_argument("--suite", default=None, help="instead of --data: a suite of families (e.g. strips16_ood)")
    parser.add_argument("--n", type=positive_int, default=None, help="with --suite: frames per family")
    parser.add_argument("--seed", type=int, default=None, help="with --suite: the frames' seed (default fixed)")
    parser.add_argument(
        "--method",
        required=True,
        help="classical method name, shipped model name, MODEL.onnx, a known-objects bundle (DIR/bundle.json), "
        "or torch weights (a run folder, NAME.pt)",
    )
    parser.add_argument(
        "--scene", default=None, help="scene of the data (default: the dataset's, else the model's, else the task's)"
    )
    parser.add_argument("--json", default=None, help="also write the result to this JSON file")
    parser.add_argument("--limit", type=positive_int, default=None, help="evaluate only the first N frames")
    parser.add_argument("--threads", type=positive_int, default=1, help="onnxruntime threads (default 1)")
    parser.add_argument("--summary", action="store_true", help="print one line of headline metrics, not the JSON")
    parser.add_argument(
        "--reference", action="store_true", help="add method-independent reference metrics (thermal: the oracle; slow)"
    )
    parser.add_argument(
        "--durations",
        type=_durations,
        default=None,
        help="thermal: contact durations (s) to evaluate, comma-separated (default 0.25,0.5,1,2,4)",
    )
    parser.add_argument(
        "--train",
        default=None,
        help="thermal few-shot methods (aligned_pca, press_aligned): the labelled recordings they learn from",
    )
    parser.add_argument(
        "--group-by", default=None, help="thermal: also report metrics per value of this touches.csv column (by_group)"
    )


def _durations(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds separated by commas, got {text!r}") from None
    if not values or not all(0 < v < 1e5 for v in values):
        raise argparse.ArgumentTypeError(f"expected positive durations (s), got {text!r}")
    return values


def _check_truth(truth: dict[str, np.ndarray], source: str) -> None:
    """The metrics compare against ``truth``: a NaN or inf there would turn them into NaN (or a
    mean over fewer frames) without a word, so it is refused, naming the array and the frame."""
    for key, values in truth.items():
        if values.dtype.kind in "fc":
            bad = ~np.isfinite(values.reshape(len(values), -1)).all(axis=1)
            if bad.any():
                raise DataError(
                    f"{source}: the truth {key!r} holds NaN or inf (first in frame {int(np.argmax(bad))}); "
                    "metrics need finite truth"
                )


def run(args: argparse.Namespace) -> int:
    if (args.data is None) == (args.suite is None):
        raise ConfigError("give either --data or --suite")
    if args.suite is not None:
        return _run_suite(args)
    task = get_task(args.task)
    scene = load_scene(args.scene) if args.scene else None
    # an adapt output folder: the classifier adapt chose (thermal_choice), with the card's scene
    adapted = load_adapted(args.method) if args.task == "thermal" else None
    if scene is None and adapted is not None:
        scene = adapted[0].card_scene_
    if scene is None and not (Path(args.data) / MANIFEST).is_file():
        # data without a scene of its own (an .npz, recordings) is read with the model's scene
        scene = model_scene(args.task, args.method)
    data = task.load_eval_data(args.data, scene)
    if args.limit is not None:
        data = data.subset(slice(0, args.limit))
    if len(data) == 0:
        raise DataError(f"{args.data}: no frames to evaluate")
    _check_truth(data.truth, args.data)
    options = {k: v for k, v in (("durations", args.durations), ("group_by", args.group_by)) if v is not None}
    if options and args.task != "thermal":
        raise ConfigError(f"--durations and --group-by apply to the thermal task, not {args.task!r}")
    start = time.perf_counter()
    if adapted is not None:
        train = task.load_eval_data(args.train or adapted[1], data.scene)
        metrics = choice_evaluate(train, data, adapted[0], args.durations, args.group_by)
        name = f"{args.method} (adapt's choice)"
    elif args.method in FEW_SHOT_METHODS and args.task == "thermal":
        if args.train is None:
            raise ConfigError(f"--method {args.method} learns from labelled touches: give --train LABELLED_DIR")
        train = task.load_eval_data(args.train, data.scene)
        metrics = few_shot_evaluate(args.method, train, data, args.durations, args.group_by)
        name = args.method
    else:
        if args.train is not None:
            raise ConfigError(
                f"--train applies to the few-shot methods ({', '.join(FEW_SHOT_METHODS)}), not {args.method!r}"
            )
        estimator = resolve_method(args.task, args.method, data.scene, threads=args.threads)
        metrics = task.evaluate(estimator, data, **options) if options else task.evaluate(estimator, data)
        name = estimator.name or args.method
    elapsed = time.perf_counter() - start
    if args.reference:
        metrics.update(task.reference_metrics(data))
    result = {
        "task": args.task,
        "method": name,
        "scene": data.scene.name,
        "n_frames": len(data),
        "metrics": metrics,
        "seconds": elapsed,
    }
    if args.json:
        atomic_write_json(args.json, result)
    if args.summary:
        scalars = [f"{k} {v:.4g}" for k, v in metrics.items() if isinstance(v, float) and not k.startswith("n_")]
        print(f"{result['method']:>22s} on {args.data} ({len(data)} frames): " + ", ".join(scalars[:5]))
    else:
        print(json_dumps(result))
    return 0


def _run_suite(args: argparse.Namespace) -> int:
    from synth.suite import load_suite
    from tactile_learn.suites import SUITE_SEED, evaluate_suite, suite_eval_data

    suite = load_suite(args.suite)
    if suite.base.task != args.task:
        raise ConfigError(f"--suite: {suite.name!r} is a suite of {suite.base.task!r} scenes, not {args.task!r}")
    seed = SUITE_SEED if args.seed is None else args.seed
    data = suite_eval_data(suite, args.n, seed)
    estimator = resolve_method(args.task, args.method, suite.base, threads=args.threads)
    report = evaluate_suite(estimator, data, args.task)
    result = {
        "task": args.task,
        "method": estimator.name or args.method,
        "suite": suite.name,
        "seed": seed,
        "n_frames_per_family": {name: len(d) for name, d in data.items()},
        **report,
    }
    if args.json:
        atomic_write_json(args.json, result)
    if args.summary:
        metric = get_task(args.task).primary_metric[0]
        for name, metrics in report["families"].items():
            print(f"{result['method']:>22s} {name:>16s}: {metric} {metrics.get(metric, float('nan')):.4g}")
        print(f"{result['method']:>22s} {'mean':>16s}: {metric} {report['mean_over_families'].get(metric):.4g}")
    else:
        print(json_dumps(result))
    return 0
