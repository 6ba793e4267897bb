"""Known objects among unknown ones: send a frame to a one-object specialist only when the readings name a
known object, and every other frame to the default model.

``strips_known_objects.py`` showed that, for a fixed set of known objects, the readings say which one
pressed (95 % over round 12's twelve) and a router over their specialists reaches nearly the specialists'
own margins. A sensor never meets only its known objects, and a specialist on a foreign object loses to the
rule (-0.075 on average, docs/strips.md). This asks the open-set question: how much of the known objects'
gain survives a router that must also leave every unknown object to the default, and what do unknown objects
pay for it::

    python scripts/strips_open_set.py runs/s12spec-*/specialist.onnx --suite strips16_unseen12 \\
        --open-suites strips16_unseen11 strips16_ood --other data/objects/* data/shapes-mixed-train \\
        --two-spheres data/strips16-test --json results/strips_specialists12/open_set.json

Two routers are fitted on the readings' features (``strips_experts``' MLP):

- **closed**: one class per known object (``strips_known_objects.py``'s router); a frame goes to the
  specialist of its most probable object when that probability exceeds the acceptance threshold;
- **open**: the same classes and one more, *other*, taught on frames of objects that are not known (``--other``
  folders: frames the router never judges). A frame goes to a specialist under the same rule; *other*'s
  probability counts against every known object.

The threshold is chosen on held-out frames, never on the judged suites: the lowest (at least 0.5) that sends
at most ``--false-share`` of the *other* folders' held-out frames (their last ``--val-frames`` frames, which
no router trained on) to a specialist. The judged frames: the known objects' suite (``--suite``, the
specialists' own families) and suites of objects no router or specialist saw (``--open-suites``), at seeds
other than the training data's; and the two-sphere test set. Margin: r minus the best classical rule's, per
family and seed, averaged.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import strips_unseen
from strips_experts import features, read_frames
from strips_known_objects import fit_classifier, routed_r, specialists_of, training_frames
from strips_unseen import CLASSICAL

from synth.errors import ConfigError
from synth.suite import load_suite
from tactile_learn.known_objects import choose
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.suites import suite_eval_data
from tactile_learn.tasks import get_task
from tactile_learn.train_known_objects import accept_for, other_frames_for

#: the acceptance thresholds every router is also reported at, beside the one chosen on held-out frames
SWEEP = (0.5, 0.8, 0.9, 0.95, 0.99)


def probabilities(router: tuple[Any, np.ndarray, np.ndarray], readings: np.ndarray) -> np.ndarray:
    """(B, classes) softmax of the router's logits."""
    import torch

    net, mean, scale = router
    with torch.no_grad():
        logits = net(torch.from_numpy(((features(readings) - mean) / scale).astype(np.float32)))
    return np.asarray(torch.softmax(logits, dim=1).numpy(), dtype=np.float64)


def accept_on(prob_unknown: np.ndarray, known: int, false_share: float) -> float:
    """The bundle builder's threshold (:func:`~tactile_learn.train_known_objects.accept_for`) from a router's
    probabilities on frames of unknown objects."""
    try:
        return accept_for(prob_unknown[:, :known].max(axis=1), false_share)
    except ConfigError as exc:
        raise SystemExit(f"--false-share: {exc}") from None


def per_frame_r(estimator: Any, readings: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return np.asarray(pearson_per_frame(estimator.predict(readings), truth), dtype=np.float64)


def judge_frames(
    data: Any, experts: list[Any], default: Any, rules: list[Any], routers: dict[str, Any]
) -> dict[str, Any]:
    """What routing needs of one family's frames: every specialist's and the default's per-frame r (one row per
    model, the default last), the best rule's mean r and each router's probabilities."""
    readings, truth = data.inputs, data.truth["pressure"]
    rows = [per_frame_r(e, readings, truth) for e in [*experts, default]]
    return {
        "r": np.stack(rows),
        "best_rule": max(float(np.nanmean(per_frame_r(rule, readings, truth))) for rule in rules),
        "prob": {name: probabilities(router, readings) for name, router in routers.items()},
    }


def score(judged: list[dict[str, Any]], router: str, accept: float, own: int | None) -> dict[str, float]:
    """One family over its seeds: the routed path's and the default's margins, the share of frames sent to a
    specialist, and (a known family) the share sent to its own."""
    known = judged[0]["r"].shape[0] - 1
    out: dict[str, list[float]] = {k: [] for k in ("routed", "default", "routed_r", "default_r", "to_specialist")}
    out["right_share"] = []
    for j in judged:
        choice = choose(j["prob"][router], known, accept)
        out["routed_r"].append(float(np.nanmean(routed_r(j["r"], choice))))
        out["default_r"].append(float(np.nanmean(j["r"][known])))
        out["routed"].append(out["routed_r"][-1] - j["best_rule"])
        out["default"].append(out["default_r"][-1] - j["best_rule"])
        out["to_specialist"].append(float(np.mean(choice < known)))
        if own is not None:
            out["right_share"].append(float(np.mean(choice == own)))
    return {k: float(np.mean(v)) for k, v in out.items() if v}


def summary(families: dict[str, dict[str, float]]) -> dict[str, Any]:
    keys = families[next(iter(families))].keys()
    mean = {k: float(np.mean([f[k] for f in families.values()])) for k in keys}
    below = {k: [name for name, f in families.items() if f[k] < 0] for k in ("routed", "default")}
    return {"mean": mean, "below": below}


def evaluate(args: argparse.Namespace) -> dict[str, Any]:
    specialists = specialists_of(args.specialists, args.suite)
    order = list(specialists)
    known = [read_frames(training_frames(m))[0][: args.train_frames] for m in specialists.values()]
    if min(len(k) for k in known) < args.train_frames:
        raise SystemExit(f"a specialist's training set has fewer than --train-frames {args.train_frames} frames")
    try:
        calibrate_on = "datasets" if args.hold_out_datasets else "frames"
        other = [Path(p) for p in args.other]
        other_train, other_val = other_frames_for(other, args.other_frames, args.val_frames, calibrate_on)
    except ConfigError as exc:
        raise SystemExit(str(exc)) from None
    routers = {
        "closed": fit_classifier(known, args.seed),
        "open": fit_classifier([*known, other_train], args.seed),
    }
    accept = {name: accept_on(probabilities(r, other_val), len(order), args.false_share) for name, r in routers.items()}
    base = load_suite(args.suite).base
    experts = [resolve_method("strips", specialists[f], base, threads=1) for f in order]
    default = resolve_method("strips", args.default, base, threads=1)
    rules = [resolve_method("strips", c, base, threads=1) for c in CLASSICAL]
    judged: dict[str, dict[str, list[dict[str, Any]]]] = {}
    for suite_name in [args.suite, *args.open_suites]:
        suite = load_suite(suite_name)
        judged[suite_name] = {}
        for seed in args.seeds:
            for family, data in suite_eval_data(suite, args.n, seed).items():
                if suite_name == args.suite and family not in specialists:
                    continue  # an object of the known suite without a specialist: not a known object
                one = judge_frames(data, experts, default, rules, routers)
                judged[suite_name].setdefault(family, []).append(one)
    if args.two_spheres:
        test = get_task("strips").load_eval_data(args.two_spheres)
        judged["two_spheres"] = {"two_spheres": [judge_frames(test, experts, default, rules, routers)]}
    result: dict[str, Any] = {"suite": args.suite, "open_suites": args.open_suites, "seeds": args.seeds}
    result["frames_per_family"] = args.n
    result["accept"] = accept
    result["routers"] = {}
    for name in routers:
        thresholds = sorted({accept[name], *SWEEP})
        per_threshold = []
        for t in thresholds:
            suites = {}
            for suite_name, fams in judged.items():
                own = {f: (order.index(f) if suite_name == args.suite else None) for f in fams}
                families = {f: score(j, name, t, own[f]) for f, j in fams.items()}
                two = suite_name == "two_spheres"
                suites[suite_name] = {"families": families, **({} if two else summary(families))}
            per_threshold.append({"accept": t, "chosen": t == accept[name], "suites": suites})
        result["routers"][name] = per_threshold
    return result


def markdown(result: dict[str, Any], default: str, command: str) -> str:
    suites = [result["suite"], *result["open_suites"]]
    head = "| router | accept | " + " | ".join(f"{s}: routed (below) / to a specialist" for s in suites)
    lines = [
        "# Known objects among unknown ones: a router that may leave a frame to the default",
        "",
        f"`{command}`",
        "",
        f"Known objects: `{result['suite']}`'s families; unknown: " + ", ".join(f"`{s}`" for s in result["open_suites"])
        + f". {result['frames_per_family']} frames a family at seeds " + ", ".join(str(s) for s in result["seeds"])
        + f". Margin: r minus the best classical rule's; `{default}` alone in the first row. The threshold marked"
        " * was chosen on held-out frames of other objects (never on these suites).",
        "",
        head + (" | two spheres: r / to a specialist |" if "two_spheres" in next(iter(result["routers"].values()))[0][
            "suites"] else " |"),
        "|---|---:|" + "---:|" * (len(suites) + 1),
    ]  # fmt: skip
    first = next(iter(result["routers"].values()))[0]["suites"]
    cells = [f"{first[s]['mean']['default']:+.4f} ({len(first[s]['below']['default'])}) / -" for s in suites]
    lines.append(f"| {default} alone | - | " + " | ".join(cells) + two_cell(first, "default") + " |")
    for name, per_threshold in result["routers"].items():
        for row in per_threshold:
            s_ = row["suites"]
            cells = [
                f"{s_[s]['mean']['routed']:+.4f} ({len(s_[s]['below']['routed'])}) / "
                f"{100 * s_[s]['mean']['to_specialist']:.1f} %"
                for s in suites
            ]
            mark = "*" if row["chosen"] else ""
            lines.append(f"| {name} | {row['accept']:.4f}{mark} | " + " | ".join(cells) + two_cell(s_, "routed") + " |")
    return "\n".join(lines) + "\n"


def two_cell(suites: dict[str, Any], key: str) -> str:
    if "two_spheres" not in suites:
        return ""
    f = suites["two_spheres"]["families"]["two_spheres"]
    share = "-" if key == "default" else f"{100 * f['to_specialist']:.1f} %"
    return f" | {f[key + '_r']:.4f} / {share}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("specialists", nargs="+", help="one-object specialists' .onnx (their cards beside them)")
    parser.add_argument("--suite", required=True, help="the suite whose families the specialists know")
    parser.add_argument("--open-suites", nargs="*", default=[], help="suites of objects no router saw")
    parser.add_argument("--other", nargs="+", required=True, help="datasets of objects that are not known")
    parser.add_argument("--default", default="strips16", help="the model every other frame goes to")
    parser.add_argument("--two-spheres", help="a dataset of the two-sphere test set (e.g. data/strips16-test)")
    parser.add_argument("--train-frames", type=int, default=5000, help="frames of each specialist's training set")
    parser.add_argument("--other-frames", type=int, default=24000, help="frames of the other class, over --other")
    parser.add_argument("--val-frames", type=int, default=200, help="held-out frames of each --other folder")
    parser.add_argument(
        "--hold-out-datasets",
        action="store_true",
        help="train other on every other --other dataset and choose the threshold on the rest (unseen objects)",
    )
    parser.add_argument("--false-share", type=float, default=0.01, help="unknown frames routed at the threshold")
    parser.add_argument("--seed", type=int, default=0, help="the routers' seed")
    parser.add_argument("--seeds", type=int, nargs="+", default=[5151, 6262])
    parser.add_argument("--n", type=int, default=600, help="frames per family and seed")
    parser.add_argument("--json", help="write the result here, and the Markdown table beside it (.md)")
    args = parser.parse_args(argv)
    if min(args.train_frames, args.other_frames, args.val_frames, args.n) < 1:
        raise SystemExit("--train-frames, --other-frames, --val-frames and --n must be at least 1")
    result = evaluate(args)
    command = "python scripts/strips_open_set.py " + " ".join(argv if argv is not None else sys.argv[1:])
    result["command"] = command
    strips_unseen.report(result, markdown(result, args.default, command), args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
