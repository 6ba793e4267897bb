"""Prior or information limit? Each losing family against a specialist fine-tuned on that family alone.

For every ``SUITE:FAMILY=MODEL`` (``MODEL``: a specialist's exported ``.onnx`` with its card beside it), the
family alone is drawn fresh at each seed (as a one-family suite: family index 0, so the seeds must differ
from the specialist's training and validation seeds) and scored with ``scripts/strips_unseen.py``'s
``evaluate``: r of the two classical rules, of the shipped ``--default`` model and of the specialist, and
each model's margin over the best classical rule. A specialist margin of at least :data:`PRIOR_MARGIN`
says the readings hold what the default lacks (a prior problem); one near zero or below says even a
network that knows the family cannot get past the rule at this architecture (an information limit)::

    python scripts/strips_specialists.py \\
        strips16_unseen4:hairbrush_pins=runs/spec-hairbrush_pins/model.onnx \\
        --seeds 5151 6262 --n 600 --json results/strips_specialists.json

Several models of one family (e.g. a second, longer fine-tune) are given as several entries; each is
scored on the same frames.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

import numpy as np

from synth.errors import ConfigError
from synth.suite import load_suite
from tactile_learn.methods import resolve_method
from tactile_learn.runtime import OnnxEstimator

sys.path.insert(0, str(Path(__file__).resolve().parent))
import strips_unseen

#: issue 12's floor: a margin over the best classical rule this large is a clear win
PRIOR_MARGIN = 0.05


def parse_entry(text: str) -> tuple[str, str, str]:
    """``SUITE:FAMILY=MODEL`` -> (suite, family, model); anything else is refused naming the form."""
    head, sep, model = text.partition("=")
    suite, colon, family = head.partition(":")
    if not (sep and colon and suite and family and model):
        raise ConfigError(f"{text!r}: expected SUITE:FAMILY=MODEL (e.g. strips16_unseen4:bead_loop=runs/X/model.onnx)")
    return suite, family, model


def verdict(margin: float) -> str:
    """What a specialist's margin over the best classical rule says about its family."""
    if margin >= PRIOR_MARGIN:
        return "prior: the readings hold it"
    if margin > 0:
        return "small gain: near the information limit"
    return "information limit: no gain over the rule"


def heldout_r(model: str, scene: Any) -> dict[str, Any] | None:
    """r of ``model`` on the held-out set its card names (for a specialist fine-tuned from the default,
    what it kept of the training distribution), with that set's scene and seed; None without one."""
    estimator = resolve_method("strips", model, scene, threads=1)
    if not isinstance(estimator, OnnxEstimator):
        raise ConfigError(f"{model}: not an ONNX strip model with a card (export a run first)")
    heldout = estimator.card_["metrics"].get("heldout")
    if not isinstance(heldout, dict):
        return None
    data = heldout["data"]
    return {"r": heldout["values"]["pearson_r_mean"], "scene": data["scene"], "seed": data["seed"], "n": data["n"]}


def score_family(
    suite_name: str, family: str, models: list[str], default: str, n: int, seeds: list[int]
) -> dict[str, Any]:
    """One family alone: r of the rules, the default and every specialist, and their margins."""
    suite = load_suite(suite_name)
    alone = dataclasses.replace(suite, families=(suite.family(family),))
    result = strips_unseen.evaluate(alone, [default, *models], n, seeds, log=lambda _: None)
    fam = result["families"][family]
    best_rule = max(strips_unseen.CLASSICAL, key=lambda c: fam["methods"][c]["r"])
    return {
        "suite": suite_name,
        "description": fam["description"],
        "r": {m: fam["methods"][m]["r"] for m in fam["methods"]},
        "nrmse": {m: fam["methods"][m]["nrmse"] for m in fam["methods"]},
        "best_rule": best_rule,
        "margin": {m: fam["models"][m]["margin"] for m in [default, *models]},
        "margin_per_seed": fam["margin_per_seed"],
        "losing_share": {m: fam["models"][m]["losing_share"] for m in [default, *models]},
        "verdict": {m: verdict(fam["models"][m]["margin"]) for m in models},
        "heldout": {m: heldout_r(m, suite.base) for m in [default, *models]},
    }


def _held(entry: dict[str, Any] | None) -> str:
    return "-" if entry is None else f"{entry['r']:.3f}"


def markdown(result: dict[str, Any]) -> str:
    """One row per (family, specialist): r of the rules, the default and the specialist, and the margins."""
    default = result["default"]
    lines = [
        f"# Specialists on the losing families: {result['frames_per_family']} frames a family at seeds "
        + ", ".join(str(s) for s in result["seeds"]),
        "",
        f"`{result['command']}`",
        "",
        "| family | intersection | projection | "
        f"{default} | specialist | {default} margin | specialist margin (seeds) | verdict | held-out r: {default}, "
        "specialist |",
        "|---|---:|---:|---:|---:|---:|---:|---|---:|",
    ]
    for family, fam in result["families"].items():
        for model in fam["verdict"]:
            seeds = " / ".join(f"{m:+.3f}" for m in fam["margin_per_seed"][model])
            lines.append(
                f"| {family} (`{model}`) | {fam['r']['intersection']:.3f} | {fam['r']['projection']:.3f} | "
                f"{fam['r'][default]:.3f} | {fam['r'][model]:.3f} | {fam['margin'][default]:+.3f} | "
                f"{fam['margin'][model]:+.3f} ({seeds}) | {fam['verdict'][model]} | "
                f"{_held(fam['heldout'][default])}, {_held(fam['heldout'][model])} |"
            )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("entries", nargs="+", help="SUITE:FAMILY=MODEL, MODEL an exported .onnx with its card")
    parser.add_argument("--default", default="strips16", help="the shipped model the specialists are compared with")
    parser.add_argument("--seeds", type=int, nargs="+", default=[5151, 6262])
    parser.add_argument("--n", type=int, default=600, help="frames per family and seed")
    parser.add_argument("--json", help="write the result here, and the Markdown table beside it (.md)")
    args = parser.parse_args(argv)
    grouped: dict[tuple[str, str], list[str]] = {}
    for entry in args.entries:
        suite, family, model = parse_entry(entry)
        grouped.setdefault((suite, family), []).append(model)
    families = {
        family: score_family(suite, family, models, args.default, args.n, args.seeds)
        for (suite, family), models in grouped.items()
    }
    result = {
        "default": args.default,
        "seeds": args.seeds,
        "frames_per_family": args.n,
        "prior_margin": PRIOR_MARGIN,
        "command": "python scripts/strips_specialists.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "families": families,
        "mean_margin": {
            "default": float(np.mean([f["margin"][args.default] for f in families.values()])),
            # the best specialist of each family: the most that family's readings gave a network here
            "best_specialist": float(np.mean([max(f["margin"][m] for m in f["verdict"]) for f in families.values()])),
        },
    }
    strips_unseen.report(result, markdown(result), args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
