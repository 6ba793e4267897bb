"""tactile-learn calibrate: fit your own sensor from a few labelled recordings."""

from __future__ import annotations

import argparse

from synth.errors import ConfigError
from synth.io import json_dumps
from synth.scene import load_scene
from tactile_learn.tasks import TASK_NAMES, get_task
from tactile_learn.tasks.base import Task

HELP = "fit a real sensor's own parameters from labelled recordings; writes a scene .toml"
EXAMPLES = """\
  tactile-learn calibrate --task thermal --data my_touches/ --out my_sensor.toml
  tactile-learn generate --scene my_sensor.toml --n 50000 --seed 1 --out data/mine-train
  tactile-learn calibrate --task fsr --data presses.npz --out my_film.toml
The thermal task reads a folder with touches.csv (file,material[,...]) and one CSV per touch
(time_s,temperature_c[,passive_c][,force]); with a passive or force column, or labels that are
families (metal, wood) or your classes (--classes), the real-sensor model is fitted (lags, heater,
drift, contact build-up, passive channel) and its report is written beside the scene (.json).
fsr: an .npz (or dataset folder) of known presses, 'readings' (B, 6) ADC codes, 'xy_mm' (B, 2) and
'force_n' (B,), a few on top of each of the six sensors; capacitive: 'readings' and the known tab loads
'cell_load', both (B, F, N, M). strips has no calibration. The output is a scene file that generate,
train and eval accept wherever a scene name goes."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", required=True, choices=TASK_NAMES)
    parser.add_argument("--data", required=True, help="labelled recordings")
    parser.add_argument("--out", required=True, help="scene .toml to write")
    parser.add_argument("--scene", default=None, help="starting scene (default: the task's)")
    parser.add_argument(
        "--channels",
        default=None,
        choices=["heated", "all"],
        help="thermal: the classifier's channels (default: all recorded)",
    )
    parser.add_argument("--classes", default=None, help="thermal: TOML file mapping your class names to materials")


def calibrated_tasks() -> tuple[str, ...]:
    """The tasks with a calibration of their own (the others keep Task's, which has none)."""
    return tuple(name for name in TASK_NAMES if type(get_task(name)).calibrate is not Task.calibrate)


def run(args: argparse.Namespace) -> int:
    task = get_task(args.task)
    if args.task not in calibrated_tasks():
        raise ConfigError(
            f"--task {args.task}: this sensor has no calibration (calibrate supports {', '.join(calibrated_tasks())})"
        )
    scene = load_scene(args.scene or task.default_scene)
    if args.task == "thermal":
        from synth.materials import load_class_map

        class_map = load_class_map(args.classes) if args.classes else None
        summary = task.calibrate(args.data, args.out, scene, channels=args.channels, class_map=class_map)  # type: ignore[call-arg]
    elif args.channels or args.classes:
        raise ConfigError("--channels and --classes apply to the thermal task")
    else:
        summary = task.calibrate(args.data, args.out, scene)
    print(json_dumps(summary))
    return 0
