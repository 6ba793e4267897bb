"""tactile-learn learn-object: a strip specialist for an object from unlabelled readings of it."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from synth.errors import ConfigError
from synth.scene import Scene
from tactile_learn.cli.common import non_negative_float, positive_int

HELP = "learn an object's shape from unlabelled strip readings of it and train a specialist for it"
EXAMPLES = """\
  # readings of one object pressed a few hundred to a few thousand times, anywhere, at any angle
  tactile-learn learn-object --readings my_presses.npz --scene strips16 --out objects/stapler
  tactile-learn eval --task strips --data stapler_test.npz --method objects/stapler/specialist.onnx
  # several learned objects behind a router that leaves every other frame to the default
  tactile-learn objects --learned objects --other data/mixed-train data/other-objects/* --out bundles/desk
The readings are an .npz with 'readings' (frames, N+M) or a dataset folder (only its readings are read:
no pressure map, no label). Frames without a press and saturated frames are left out; at least
--min-frames must remain. The folder gets template.npz (the fitted shape), the rendered train/ and val/
datasets, the fine-tune's run/, specialist.onnx with its card, and object.json (written last: frames
used, the fit's residual, the command, the readings' path and checksum: `tactile-learn objects --learned`
fits its router on them). docs/strips.md ("Learning an object from its readings") measures it on rounds 11
and 12. Needs torch; about 8 minutes on one core with the defaults."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--readings", required=True, help=".npz with 'readings', or a dataset folder")
    parser.add_argument("--out", required=True, help="the object's folder (new or empty)")
    parser.add_argument("--scene", default=None, help="the sensor's scene (default: the dataset's, else strips16)")
    parser.add_argument("--frames", type=positive_int, default=1500, help="frames fitted (default 1500)")
    parser.add_argument("--min-frames", type=positive_int, default=200, help="fewer usable frames is an error")
    parser.add_argument("--iterations", type=positive_int, default=20, help="fit rounds (default 20)")
    parser.add_argument("--n-train", type=positive_int, default=24000, help="rendered training frames")
    parser.add_argument("--n-val", type=positive_int, default=2000, help="rendered validation frames")
    parser.add_argument("--vary", type=non_negative_float, default=0.4, help="parts' load variation (log s.d.)")
    parser.add_argument("--epochs", type=positive_int, default=8)
    parser.add_argument("--init", default="strips16_generic", help="weights the specialist starts from")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=positive_int, default=1, help="torch threads (default 1)")


def _scene(args: argparse.Namespace) -> Scene:
    from synth.dataset import Dataset
    from synth.scene import load_scene

    source = Path(args.readings)
    if args.scene is not None:
        scene = load_scene(args.scene)
    elif source.is_dir():
        scene = Dataset(source).scene
    else:
        scene = load_scene("strips16")
    if scene.task != "strips":
        raise ConfigError(f"--scene: {scene.name!r} is a {scene.task} scene; learn-object reads strip arrays")
    return scene


def run(args: argparse.Namespace) -> int:
    try:
        from tactile_learn.learn_object import LearnConfig, learn_object
        from tactile_learn.object_tomography import TomographyConfig
    except ImportError:
        raise ConfigError(
            "tactile-learn learn-object fits and trains with torch: pip install 'tactile-learn[train]'"
        ) from None
    from synth.dataset import load_arrays
    from tactile_learn.provenance import portable_path

    scene = _scene(args)
    config = LearnConfig(
        frames=args.frames,
        n_train=args.n_train,
        n_val=args.n_val,
        vary=args.vary,
        epochs=args.epochs,
        init=args.init,
        seed=args.seed,
        threads=args.threads,
        min_frames=args.min_frames,
    )
    tomography = TomographyConfig(iterations=args.iterations, seed=args.seed)
    readings = load_arrays(args.readings, ["readings"])["readings"]
    recipe = [
        "tactile-learn",
        "learn-object",
        "--readings",
        portable_path(args.readings),
        "--out",
        portable_path(args.out),
    ]
    recipe += ["--scene", scene.name, "--frames", str(args.frames)]
    recipe += ["--iterations", str(args.iterations), "--n-train", str(args.n_train), "--n-val", str(args.n_val)]
    recipe += ["--vary", str(args.vary), "--epochs", str(args.epochs), "--init", args.init, "--seed", str(args.seed)]
    record = learn_object(
        readings,
        scene,
        Path(args.out),
        config,
        tomography,
        command=shlex.join(recipe),
        readings_path=str(args.readings),  # as given: the bundle builder reads them again from there
    )
    f = record["frames"]
    print(
        f"frames: {f['used']} of {f['frames']} used ({f['idle']} idle, {f['saturated']} saturated), "
        f"{f['fitted']} fitted"
    )
    print(f"fit: median residual {record['fit']['residual_median']:.3f} of the loads")
    print(f"wrote {Path(args.out) / 'specialist.onnx'} (r {record['validation_r']:.3f} on rendered validation frames)")
    return 0
