"""tactile-learn objects: build a known-objects bundle (a router over one-object strip specialists)."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from synth.errors import ConfigError
from tactile_learn.cli.common import non_negative_float, positive_int

HELP = "build a known-objects bundle: each known object's frames to its own specialist, the rest to the default"
EXAMPLES = """\
  # 1. a specialist per object: frames of the object, then the objects' expert fine-tuned on them
  tactile-learn generate --scene my_objects/bobby_pin.toml --n 24000 --seed 1 --out data/bobby_pin-train
  tactile-learn train --task strips --data data/bobby_pin-train --val data/bobby_pin-val \\
      --init models/strips16_generic.pt --epochs 8 --lr 3e-4 --out runs/bobby_pin
  tactile-learn export runs/bobby_pin --out runs/bobby_pin/specialist.onnx
  # 2. the bundle: a router fitted on the specialists' own training frames and on frames of other objects
  tactile-learn objects --object bobby_pin=runs/bobby_pin/specialist.onnx \\
      --object cookie=runs/cookie/specialist.onnx --other data/mixed-train data/other-objects/* --out bundles/kitchen
  # 3. use it wherever a method is named
  tactile-learn eval --task strips --data data/kitchen-test --method bundles/kitchen/bundle.json
  # or, label-free: objects learned from their readings (tactile-learn learn-object), every one in a folder
  tactile-learn objects --learned runs/learned --other data/mixed-train data/other-objects/* --out bundles/mine
Each object's frames are the dataset its specialist's card names, a learned object's the readings it was
learned from (object.json names them with their checksum), or --data NAME=DIR. The threshold
is the lowest probability (at least 0.5) that sends at most --false-share of held-out frames of other
objects to a specialist: by default the last frames of every second --other dataset, whose objects the
router never trains on (give many kinds of objects); bundle.json records it with what it cost. Objects
unlike all of these can still be sent to a specialist: docs/strips.md, "Known objects among unknown
ones", measures how often. Needs torch (the router is fitted here)."""


def _pairs(values: list[str] | None, flag: str) -> dict[str, Path]:
    out: dict[str, Path] = {}
    for value in values or []:
        name, sep, path = value.partition("=")
        if not sep or not name or not path:
            raise ConfigError(f"{flag} {value!r}: expected NAME=PATH")
        if name in out:
            raise ConfigError(f"{flag}: {name!r} given twice")
        out[name] = Path(path)
    return out


def _recipe(args: argparse.Namespace, objects: dict[str, Path], data: dict[str, Path]) -> list[str]:
    """The command that builds this bundle again, with portable paths (the bundle records it)."""
    from tactile_learn.provenance import portable_path

    recipe = ["tactile-learn", "objects"]
    for flag, pairs in (("--object", objects), ("--data", data)):
        for name, path in pairs.items():
            recipe += [flag, f"{name}={portable_path(path)}"]
    if args.learned:
        recipe += ["--learned", *(portable_path(p) for p in args.learned)]
    recipe += ["--other", *(portable_path(p) for p in args.other), "--out", portable_path(args.out)]
    recipe += ["--default", args.default, "--train-frames", str(args.train_frames)]
    recipe += ["--other-frames", str(args.other_frames), "--val-frames", str(args.val_frames)]
    recipe += ["--false-share", str(args.false_share), "--calibrate-on", args.calibrate_on]
    return [*recipe, "--seed", str(args.seed)]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--object", action="append", default=None, help="NAME=SPECIALIST.onnx or NAME=LEARNED_OBJECT_DIR (repeatable)"
    )
    parser.add_argument(
        "--learned",
        nargs="+",
        default=None,
        help="folders of learned objects (tactile-learn learn-object): all of them",
    )
    parser.add_argument("--other", nargs="+", required=True, help="datasets of objects that are not known")
    parser.add_argument("--out", required=True, help="the bundle's folder (new)")
    parser.add_argument("--default", default="strips16", help="the model every other frame goes to")
    parser.add_argument("--data", action="append", default=None, help="NAME=DIR: an object's frames (repeatable)")
    parser.add_argument(
        "--train-frames",
        type=positive_int,
        default=5000,
        help="at most this many frames of each object to train on (default 5000; a shorter recording gives all "
        "but its held-out frames, and at least 100)",
    )
    parser.add_argument("--other-frames", type=positive_int, default=60000, help="frames over --other to train on")
    parser.add_argument("--val-frames", type=positive_int, default=200, help="held-out frames of each dataset")
    parser.add_argument("--false-share", type=non_negative_float, default=0.01, help="held-out other frames routed")
    parser.add_argument(
        "--calibrate-on",
        choices=["datasets", "frames"],
        default=None,
        help="choose the threshold on every second --other dataset, never trained on (default with two or more "
        "--other datasets), or on held-out frames of every --other dataset (the default with one)",
    )
    parser.add_argument("--seed", type=int, default=0, help="the router's seed")


def run(args: argparse.Namespace) -> int:
    try:
        from tactile_learn.train_known_objects import build_bundle
    except ImportError:
        raise ConfigError(
            "tactile-learn objects fits a router with torch: pip install 'tactile-learn[train]'"
        ) from None
    from tactile_learn.learned_objects import (
        is_learned_object,
        learned_objects_in,
        learned_readings,
        learned_specialist,
    )

    named = _pairs(args.object, "--object")
    data = _pairs(args.data, "--data")
    objects = {name: path for name, path in named.items() if not is_learned_object(path)}
    learned = [(name, learned_specialist(path)) for name, path in named.items() if is_learned_object(path)]
    for folder in args.learned or []:
        learned += list(learned_objects_in(folder).items())
    recorded: dict[str, Path] = {}  # a learned object's frames: the readings it was learned from (no map read)
    for name, model in learned:
        if name in objects:
            raise ConfigError(f"object {name!r} is named twice (--object and --learned)")
        objects[name] = model
        if name not in data:
            recorded[name] = learned_readings(model.parent)
    if not objects:
        raise ConfigError("name the known objects: --object NAME=PATH (repeatable) or --learned DIR")
    unknown = sorted(set(data) - set(objects))
    if unknown:
        raise ConfigError(f"--data names no --object: {', '.join(unknown)}")
    if args.calibrate_on is None:
        args.calibrate_on = "datasets" if len(args.other) >= 2 else "frames"
    command = shlex.join(_recipe(args, named, data))
    bundle = build_bundle(
        objects,
        [Path(p) for p in args.other],
        Path(args.out),
        default=args.default,
        data=recorded | data,
        train_frames=args.train_frames,
        other_frames=args.other_frames,
        val_frames=args.val_frames,
        false_share=args.false_share,
        calibrate_on=args.calibrate_on,
        seed=args.seed,
        command=command,
    )
    v = bundle["validation"]
    print(f"wrote {Path(args.out) / 'bundle.json'}: accept {bundle['accept']:.4f}")
    held = "held-out --other datasets" if args.calibrate_on == "datasets" else "held-out frames of --other"
    print(f"{held} sent to a specialist: {100 * v['other_routed_share']:.1f} %")
    for name, o in v["objects"].items():
        own, default = 100 * o["to_own_specialist"], 100 * o["to_default"]
        print(f"  {name}: {own:.1f} % of its held-out frames to its specialist, {default:.1f} % to the default")
    return 0
