"""tactile-learn calibrate: fit your own sensor from a few labelled recordings."""

from __future__ import annotations

import argparse

from synth.io import json_dumps
from synth.scene import load_scene
from tactile_learn.tasks import TASK_NAMES, get_task

HELP = "fit a real sensor's own parameters from labelled recordings; writes a scene .toml"
EXAMPLES = """\
  tactile-learn calibrate --task thermal --data my_touches/ --out my_sensor.toml
  tactile-learn generate --scene my_sensor.toml --n 50000 --seed 1 --out data/mine-train
  tactile-learn calibrate --task fsr --data presses.npz --out my_film.toml
The thermal task reads a folder with touches.csv (file,material[,...]) and one CSV per touch
(time_s,temperature_c); see the task's documentation for the fsr format. The output is a scene file
that generate, train and eval accept wherever a scene name goes."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", required=True, choices=TASK_NAMES)
    parser.add_argument("--data", required=True, help="labelled recordings")
    parser.add_argument("--out", required=True, help="scene .toml to write")
    parser.add_argument("--scene", default=None, help="starting scene (default: the task's)")


def run(args: argparse.Namespace) -> int:
    task = get_task(args.task)
    scene = load_scene(args.scene or task.default_scene)
    summary = task.calibrate(args.data, args.out, scene)
    print(json_dumps(summary))
    return 0
