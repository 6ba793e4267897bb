"""tactile-learn materials: the thermal material library, its families, and how labels resolve."""

from __future__ import annotations

import argparse

from synth.materials import FAMILIES, effusivity_range, library, load_class_map, resolve_label

HELP = "list the thermal material library and its families (what touch labels may name)"
EXAMPLES = """\
  tactile-learn materials
  tactile-learn materials --label wood              # which materials a label stands for
  tactile-learn materials --classes my_classes.toml # check your own classes
A touch label (touches.csv, column material) is a material, a family (every material of it), or a
class of your own, given to adapt/calibrate with --classes FILE.toml:
  [classes]
  metal = ["aluminium", "mild_steel"]
  wood = ["wood"]                                    # a family: oak, pine, plywood"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--label", default=None, help="show the materials a label stands for")
    parser.add_argument("--classes", default=None, help="a TOML file with a [classes] table to check and show")


def run(args: argparse.Namespace) -> int:
    class_map = load_class_map(args.classes) if args.classes else None
    if args.label:
        mats = resolve_label(args.label, class_map)
        print(f"{args.label}: {', '.join(m.name for m in mats)}")
        return 0
    if class_map:
        for name in class_map:
            print(f"{name:16s} {', '.join(m.name for m in resolve_label(name, class_map))}")
        return 0
    print(
        f"{'material':16s} {'family':12s} {'k W/(m K)':>10s} {'rho kg/m3':>10s} {'c J/(kg K)':>10s} "
        f"{'e W s^0.5/(m2 K)':>18s} {'alpha mm2/s':>11s}"
    )
    for m in library():
        lo, hi = effusivity_range(m)
        print(
            f"{m.name:16s} {m.family:12s} {m.k_w_mk:10.3g} {m.rho_kg_m3:10.4g} {m.c_j_kgk:10.4g} "
            f"{m.effusivity:8.0f} ({lo:.0f}-{hi:.0f}) {m.diffusivity_mm2_s:11.3g}"
        )
    print(f"families: {', '.join(FAMILIES)}")
    return 0
