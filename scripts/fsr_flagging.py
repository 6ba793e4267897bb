"""How often does the FSR film's one-press check (column ``p_one_press``) catch two simultaneous
presses and large flat indenters, and how often does it flag a normal single press by mistake?

Frames on films never seen in training (seed below): presses of 1-10 N inside the four triangles (the
paper's conditions), for each kind: one round press, two round presses at once, one flat indenter of
10-20 mm radius; plus the standard fsr6 distribution (single presses anywhere, 0.1-10 N). Rates are
over frames where the method detects a contact.

    python scripts/fsr_flagging.py --n 4000 --json results/fsr_flagging.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys

import numpy as np

from synth.config import replace
from synth.dataset import simulate_shard
from synth.scene import Scene, load_scene
from tactile_learn.methods import resolve_method

SEED = 31337


def _scene(base: Scene, **stimulus: object) -> Scene:
    config = base.sensor
    for key, value in stimulus.items():
        config = replace(config, f"stimulus.{key}", value)
    return dataclasses.replace(base, sensor=config)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=4000, help="frames per kind")
    parser.add_argument("--methods", nargs="+", default=["triangulation", "triangulation_fit", "fsr"])
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    base = load_scene("fsr6")
    paper = {"no_contact_fraction": 0.0, "inside_fraction": 1.0, "force_range_n": (1.0, 10.0)}
    kinds = {
        "one press (paper conditions)": _scene(base, **paper),
        "two presses": _scene(base, **paper, second_press_fraction=1.0),
        "flat indenter 10-20 mm": _scene(base, **paper, flat_fraction=1.0),
        "one press anywhere (fsr6)": base,
    }
    frames = {name: simulate_shard(scene, SEED, i, args.n) for i, (name, scene) in enumerate(kinds.items())}
    two = frames["two presses"]
    apart = np.linalg.norm(two["xy_mm"] - two["latent_second_xy_mm"], axis=1) >= 10.0
    results: dict[str, dict[str, float]] = {}
    for method in args.methods:
        est = resolve_method("fsr", method, base)
        results[method] = {}
        for name, arrays in frames.items():
            pred = est.predict(arrays["readings"])
            detected = pred[:, 3] > 0.5
            results[method][name] = float((pred[detected, 5] < 0.5).mean()) if detected.any() else float("nan")
            if name == "two presses":
                sel = detected & apart
                results[method]["two presses >= 10 mm apart"] = float((pred[sel, 5] < 0.5).mean())
    kinds_shown = list(results[args.methods[0]])
    print("| method | " + " | ".join(f"flagged: {k}" for k in kinds_shown) + " |")
    print("|---|" + "---:|" * len(kinds_shown))
    for method, rates in results.items():
        print(f"| {method} | " + " | ".join(f"{100 * v:.1f} %" for v in rates.values()) + " |")
    if args.json:
        from synth.io import atomic_write_json

        atomic_write_json(
            args.json,
            {
                "seed": SEED,
                "frames_per_kind": args.n,
                "flagged_share": results,
                "command": "python scripts/fsr_flagging.py " + " ".join(argv if argv is not None else sys.argv[1:]),
            },
        )
    json.dumps(results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
