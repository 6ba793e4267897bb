"""How much could any router between a routed card's two members give? (issue 12; docs/strips.md, "Round 10")

For every family of the suites named, the margin over the best classical rule (mean r at each seed, as
``strips_unseen.py`` reports it) of the card's own network alone (``route=False``), its generic member alone,
the routed card, and an oracle that picks, frame by frame, the member with the higher r (a bound no router on
the readings can beat; the per-family choice is a looser one). Beside them, two ways of mixing the members'
maps instead of choosing one: fixed blends ``(1 - w) own + w generic`` at each ``w`` of :data:`BLENDS`, and
``soft``, each frame's blend weighted by the router's probability of "generic" (docs/strips.md, "Round 11")::

    python scripts/strips_route_oracle.py strips16_unseen10 strips16_ood --json results/strips_objects/frame_oracle.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from synth.scene import load_scene
from synth.suite import load_suite, suite_frames
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.runtime import OnnxEstimator, read_card

#: the fixed blend weights of the generic member's map (``blend_W``)
BLENDS = (0.25, 0.5, 0.75)
KINDS = ("own", "generic", "routed", "frame_oracle", *(f"blend_{w}" for w in BLENDS), "soft")


def members_of(model: Path) -> dict[str, OnnxEstimator]:
    """The routed card's own network alone, its generic member alone, and the routed card."""
    card = read_card(model)
    if "route" not in card:
        raise SystemExit(f"{model}: the card routes no frames (no route block)")
    return {
        "own": OnnxEstimator(model, route=False).prepare(),
        "generic": OnnxEstimator(model.parent / card["route"]["generic_model"]).prepare(),
        "routed": OnnxEstimator(model).prepare(),
    }


def family_margins(
    members: dict[str, OnnxEstimator], readings: np.ndarray, truth: np.ndarray, rules: dict[str, Any]
) -> dict[str, float]:
    """One family's frames: each kind's mean r minus the best rule's mean r."""
    maps = {k: m.predict(readings) for k, m in members.items()}
    r = {k: pearson_per_frame(v, truth) for k, v in maps.items()}
    best_rule = max(float(np.nanmean(pearson_per_frame(e.predict(readings), truth))) for e in rules.values())
    r["frame_oracle"] = np.fmax(r["own"], r["generic"])
    own, generic = maps["own"].astype(np.float64), maps["generic"].astype(np.float64)
    for w in BLENDS:
        r[f"blend_{w}"] = pearson_per_frame((1.0 - w) * own + w * generic, truth)
    routed = members["routed"].route_
    assert routed is not None  # members_of refuses a card without a route
    route = routed[0]
    # the router's probability of "generic" (a NaN logit - a refused frame - never reaches here)
    p = 1.0 / (1.0 + np.exp(-np.asarray(route.logit(readings), dtype=np.float64)))
    p = p.reshape((-1,) + (1,) * (own.ndim - 1))
    r["soft"] = pearson_per_frame((1.0 - p) * own + p * generic, truth)
    return {k: float(np.nanmean(v)) - best_rule for k, v in r.items()}


def evaluate(model: Path, suites: list[str], seeds: list[int], n: int) -> dict[str, Any]:
    base = load_scene("strips16")
    rules = {name: resolve_method("strips", name, base) for name in ("intersection", "projection")}
    members = members_of(model)
    out: dict[str, Any] = {"model": str(model), "seeds": seeds, "frames_per_family": n, "suites": {}}
    for name in suites:
        per_seed: dict[str, list[dict[str, float]]] = {}
        for seed in seeds:
            for fam, arrays in suite_frames(load_suite(name), n, seed).items():
                readings = np.asarray(arrays["readings"], dtype=np.float32)
                truth = np.asarray(arrays["pressure"], dtype=np.float32)
                per_seed.setdefault(fam, []).append(family_margins(members, readings, truth, rules))
        families = {f: {k: float(np.mean([row[k] for row in rows])) for k in KINDS} for f, rows in per_seed.items()}
        mean = {k: float(np.mean([f[k] for f in families.values()])) for k in KINDS}
        below = {k: sum(f[k] < 0 for f in families.values()) for k in KINDS}
        family_best = float(np.mean([max(f["own"], f["generic"]) for f in families.values()]))
        out["suites"][name] = {"mean": mean, "families_below": below, "family_oracle": family_best}
        out["suites"][name]["families"] = families
        print(name, {k: round(v, 4) for k, v in mean.items()}, "below", below, "family oracle", round(family_best, 4))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("suites", nargs="+", help="suite names or TOML files")
    parser.add_argument("--model", type=Path, default=Path("models/strips16.onnx"), help="a routed strip card")
    parser.add_argument("--seeds", type=int, nargs="+", default=[5151, 6262])
    parser.add_argument("--n", type=int, default=600, help="frames per family and seed")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    result = evaluate(args.model, args.suites, args.seeds, args.n)
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
