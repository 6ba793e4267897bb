"""Do the readings name which of a fixed set of known objects pressed? A router over one-object specialists.

Round 12's specialists (docs/strips.md, "Round 12's objects, each with its own specialist") each beat the
rule on their own object and lose on the others. If a frame's readings say which object pressed, a
classifier could send each frame to its object's specialist: a design for a sensor that only ever meets a
fixed set of known objects (it gives nothing for objects outside the set, the issue's unseen shapes). This
trains that classifier and judges it on the suite's frames::

    python scripts/strips_known_objects.py runs/s12spec-*/specialist.onnx --suite strips16_unseen12 \\
        --train-frames 5000 --seeds 5151 6262 --n 600 --json results/strips_specialists12/known_objects.json

The classifier is ``strips_experts``' MLP (the readings' features -> 96 -> 96 -> one logit per object, cross
entropy, 60 epochs), fitted on the first ``--train-frames`` frames of every specialist's own training
dataset (its card names it), so it never sees the judged frames (other seeds). Per family: the share of
frames routed to the right specialist, and r and margin over the best classical rule of the routed path,
beside the right specialist on every frame (the oracle) and the shipped default.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import strips_unseen
from strips_experts import features, read_frames
from strips_transfer import card_family
from strips_unseen import CLASSICAL

from synth.suite import load_suite
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.suites import suite_eval_data
from tactile_learn.train_known_objects import fit_classes


def specialists_of(models: list[str], suite: str) -> dict[str, str]:
    """Family -> specialist, in the order given; refuses a model that is no one-object specialist of the suite,
    and two specialists of one family."""
    out: dict[str, str] = {}
    for model in models:
        family = card_family(model, suite)
        if family is None:
            raise SystemExit(f"{model}: its card names no single family of {suite} (not a specialist)")
        if family in out:
            raise SystemExit(f"two specialists of {family}: {out[family]} and {model}")
        out[family] = model
    if len(out) < 2:
        raise SystemExit("a router needs the specialists of at least two objects")
    return out


def training_frames(model: str) -> Path:
    """The training dataset the specialist's card names."""
    card = json.loads(Path(model).with_suffix(".json").read_text())
    return Path(card["training"]["data"]["path"])


def fit_router(folders: list[Path], frames: int, seed: int) -> tuple[Any, np.ndarray, np.ndarray]:
    """The object classifier on the first ``frames`` frames of each folder (label: the folder's index), with the
    features' mean and scale it normalises by."""
    classes = []
    for folder in folders:
        readings, _ = read_frames(folder)
        if len(readings) < frames:
            raise SystemExit(f"{folder}: {len(readings)} frames, fewer than --train-frames {frames}")
        classes.append(readings[:frames])
    return fit_classifier(classes, seed)


def fit_classifier(classes: list[np.ndarray], seed: int) -> tuple[Any, np.ndarray, np.ndarray]:
    """``strips_experts``' MLP fitted to tell the readings of each array in ``classes`` (label: its index) apart,
    with the features' mean and scale it normalises by: the bundle builder's own fit
    (:func:`tactile_learn.train_known_objects.fit_classes`; its features are ``strips_experts.features``)."""
    return fit_classes(classes, seed)


def classify(net: Any, mean: np.ndarray, scale: np.ndarray, readings: np.ndarray) -> np.ndarray:
    import torch

    with torch.no_grad():
        logits = net(torch.from_numpy(((features(readings) - mean) / scale).astype(np.float32)))
    return logits.argmax(dim=1).numpy()


def routed_r(per_model_r: np.ndarray, choice: np.ndarray) -> np.ndarray:
    """Per-frame r of the routed path: frame i answered by model ``choice[i]`` (rows of ``per_model_r``)."""
    return per_model_r[choice, np.arange(per_model_r.shape[1])]


def evaluate(
    suite_name: str,
    specialists: dict[str, str],
    router: tuple[Any, np.ndarray, np.ndarray],
    default: str,
    n: int,
    seeds: list[int],
) -> dict[str, Any]:
    suite = load_suite(suite_name)
    order = list(specialists)
    estimators = {m: resolve_method("strips", m, suite.base, threads=1) for m in [*CLASSICAL, default]}
    experts = [resolve_method("strips", specialists[f], suite.base, threads=1) for f in order]
    rows: dict[str, list[dict[str, float]]] = {f: [] for f in order}
    for seed in seeds:
        data = suite_eval_data(suite, n, seed)
        for family in order:
            frames = data[family]
            truth = frames.truth["pressure"]

            def r_of(estimator: Any, readings: np.ndarray = frames.inputs, truth: np.ndarray = truth) -> np.ndarray:
                return np.asarray(pearson_per_frame(estimator.predict(readings), truth), dtype=np.float64)

            per_expert = np.stack([r_of(e) for e in experts])
            choice = classify(router[0], router[1], router[2], frames.inputs)
            best_rule = max(float(np.nanmean(r_of(estimators[c]))) for c in CLASSICAL)
            own = order.index(family)
            rows[family].append(
                {
                    "best_rule": best_rule,
                    "routed": float(np.nanmean(routed_r(per_expert, choice))) - best_rule,
                    "oracle": float(np.nanmean(per_expert[own])) - best_rule,
                    "default": float(np.nanmean(r_of(estimators[default]))) - best_rule,
                    "right_share": float(np.mean(choice == own)),
                }
            )
    families = {f: {k: float(np.mean([row[k] for row in rows[f]])) for k in rows[f][0]} for f in order}
    mean = {
        k: float(np.mean([v[k] for v in families.values()])) for k in ("routed", "oracle", "default", "right_share")
    }
    below = {k: [f for f, v in families.items() if v[k] < 0] for k in ("routed", "oracle", "default")}
    return {
        "suite": suite_name,
        "seeds": seeds,
        "frames_per_family": n,
        "families": families,
        "mean": mean,
        "below": below,
    }


def markdown(result: dict[str, Any], default: str, command: str) -> str:
    lines = [
        f"# A router over one-object specialists on `{result['suite']}`: {result['frames_per_family']} frames a "
        "family at seeds " + ", ".join(str(s) for s in result["seeds"]),
        "",
        f"`{command}`",
        "",
        "Margin over the best classical rule; routed right: the share of the family's frames the classifier sends "
        "to its own specialist.",
        "",
        f"| family | routed right | routed | own specialist (oracle) | {default} |",
        "|---|---:|---:|---:|---:|",
    ]
    for family, v in result["families"].items():
        lines.append(
            f"| {family} | {100 * v['right_share']:.1f} % | {v['routed']:+.3f} | {v['oracle']:+.3f} | "
            f"{v['default']:+.3f} |"
        )
    m, b = result["mean"], result["below"]
    lines.append(
        f"| **mean** (below the rule) | {100 * m['right_share']:.1f} % | {m['routed']:+.4f} ({len(b['routed'])}) | "
        f"{m['oracle']:+.4f} ({len(b['oracle'])}) | {m['default']:+.4f} ({len(b['default'])}) |"
    )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("specialists", nargs="+", help="one-object specialists' .onnx (their cards beside them)")
    parser.add_argument("--suite", required=True)
    parser.add_argument("--default", default="strips16", help="the model the routed path is compared with")
    parser.add_argument("--train-frames", type=int, default=5000, help="frames of each specialist's training set")
    parser.add_argument("--seed", type=int, default=0, help="the classifier's seed")
    parser.add_argument("--seeds", type=int, nargs="+", default=[5151, 6262])
    parser.add_argument("--n", type=int, default=600, help="frames per family and seed")
    parser.add_argument("--json", help="write the result here, and the Markdown table beside it (.md)")
    args = parser.parse_args(argv)
    if args.train_frames < 1 or args.n < 1:
        raise SystemExit("--train-frames and --n must be at least 1")
    specialists = specialists_of(args.specialists, args.suite)
    router = fit_router([training_frames(m) for m in specialists.values()], args.train_frames, args.seed)
    result = evaluate(args.suite, specialists, router, args.default, args.n, args.seeds)
    command = "python scripts/strips_known_objects.py " + " ".join(argv if argv is not None else sys.argv[1:])
    result["command"] = command
    table = markdown(result, args.default, command)
    strips_unseen.report(result, table, args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
