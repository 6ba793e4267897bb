"""tactile-learn scenes: list the shipped scenes or show one."""

from __future__ import annotations

import argparse

from synth.config import dumps_toml
from synth.scene import available_scenes, load_scene

HELP = "list the shipped scenes, or print one as TOML"
EXAMPLES = """\
  tactile-learn scenes
  tactile-learn scenes --show strips16 > my_sensor.toml   # a starting point for your own sensor"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--show", default=None, help="scene name or .toml path to print in full")


def run(args: argparse.Namespace) -> int:
    if args.show:
        print(dumps_toml(load_scene(args.show).to_dict()), end="")
        return 0
    for name in available_scenes():
        scene = load_scene(name)
        print(f"{name:16s} {scene.task:8s} {scene.digest}  {scene.description}")
    return 0
