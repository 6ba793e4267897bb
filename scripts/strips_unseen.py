"""Issue 12's "independent shapes you have not seen": the strip models on ``strips16_unseen``.

Every family of the suite (presses no strip scene or suite defines: a knuckle, a stylus, five
fingertips, a pen, ...) is drawn fresh at each seed; on the same frames, r and NRMSE of the two
classical rules (intersection, projection) and of each model, the model's margin over the best
classical rule of that family, and what its readings-residual flag does there
(``tactile_learn.strips_guard``): the share of frames it flags, the share of the frames the model
answers clearly worse than the best classical rule (per-frame r lower by more than
:data:`LOSS_MARGIN`) that it flags, and r of the guarded path (the intersection rule on flagged
frames). Writes the JSON and a Markdown table beside it::

    python scripts/strips_unseen.py --seeds 5151 6262 --n 600 --test data/mixed-test \\
        --json results/strips_unseen.json

A model is a shipped name or the path of any ``.onnx`` model with its card beside it, e.g. a
candidate exported from a training run (``tactile-learn export runs/NAME --out runs/NAME/model.onnx``)::

    python scripts/strips_unseen.py strips16 runs/NAME/model.onnx --suite strips16_unseen3 \\
        --seeds 5151 6262 --n 600 --test data/mixed-test --json results/candidate_unseen3.json
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from synth.io import atomic_write_json, atomic_write_text
from synth.suite import Suite, load_suite
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.strips_guard import CHECK_OUTPUTS, CheckedStripModel
from tactile_learn.suites import suite_eval_data
from tactile_learn.tasks import get_task
from tactile_learn.tasks.base import EvalData

CLASSICAL = ("intersection", "projection")
#: a frame the model "loses" is one whose r is this much below the best classical rule's r there
#: (smaller differences are within what two fair answers to the same readings differ by)
LOSS_MARGIN = 0.05


def _mean(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if finite.size else float("nan")


def family_result(
    data: EvalData, estimators: dict[str, Any], checked: dict[str, CheckedStripModel], models: list[str]
) -> dict[str, Any]:
    """One family at one seed: every method's r/NRMSE, each model's margin and, for the models with
    a readings residual (``checked``), the flag's figures."""
    task = get_task("strips")
    truth = data.truth["pressure"]
    methods: dict[str, dict[str, float]] = {}
    frame_r: dict[str, np.ndarray] = {}
    for name, estimator in estimators.items():
        pred = estimator.predict(data.inputs)
        m = task.metrics(pred, data)
        methods[name] = {"r": m["pearson_r_mean"], "nrmse": m["nrmse"]}
        frame_r[name] = pearson_per_frame(pred, truth)
    best_name = max(CLASSICAL, key=lambda c: methods[c]["r"])
    best_frame = np.fmax(frame_r[CLASSICAL[0]], frame_r[CLASSICAL[1]])
    results: dict[str, dict[str, float]] = {}
    for name in models:
        losing = frame_r[name] < best_frame - LOSS_MARGIN
        margin = methods[name]["r"] - methods[best_name]["r"]
        if name not in checked:  # no residual outputs: no flag to measure
            results[name] = {"margin": margin, "losing_share": float(losing.mean())}
            continue
        guard = checked[name]
        out = guard.check(data.inputs)
        flagged = out["flagged"]
        guarded = task.metrics(out["pressure"], data)
        results[name] = {
            "margin": margin,
            "flagged_share": float(flagged.mean()),
            "losing_share": float(losing.mean()),
            "losing_flagged_share": float(flagged[losing].mean()) if losing.any() else float("nan"),
            "r_flagged": _mean(frame_r[name][flagged]),
            "r_unflagged": _mean(frame_r[name][~flagged]),
            "r_guarded": guarded["pearson_r_mean"],
            "residual_median": float(np.median(out["residual"])),
            # how far below the flag the frames it should catch sit: their residual over the threshold
            "losing_residual_over_threshold_p90": (
                float(np.percentile(out["residual"][losing], 90) / guard.thresholds_["residual"])
                if losing.any()
                else float("nan")
            ),
            # a residual threshold here would flag half of the losing frames
            "losing_residual_median": float(np.median(out["residual"][losing])) if losing.any() else float("nan"),
        }
    return {"frames": len(truth), "best_classical": best_name, "methods": methods, "models": results}


def evaluate(
    suite: Suite, models: list[str], n: int, seeds: list[int], test: EvalData | None = None, log: Any = print
) -> dict[str, Any]:
    """Every family at every seed, and the mean over seeds; with ``test`` (frames of the models'
    training distribution) also the share of those a residual threshold low enough to flag half of
    a family's losing frames would flag: the price of catching that family with the residual."""
    estimators = {name: resolve_method("strips", name, suite.base, threads=1) for name in [*CLASSICAL, *models]}
    checked = {}
    for name in models:
        model = estimators[name]
        if not isinstance(model, OnnxEstimator):
            raise SystemExit(
                f"{name}: not an ONNX strip model (torch weights: export them first, "
                "tactile-learn export RUN --out MODEL.onnx, and pass MODEL.onnx)"
            )
        if set(CHECK_OUTPUTS) <= {o["name"] for o in model.card_["outputs"]}:
            checked[name] = CheckedStripModel(model, fallback="intersection").prepare()
        else:
            log(f"{name}: no readings-residual outputs; r and NRMSE only")
    per_seed: dict[str, dict[str, Any]] = {}
    for seed in seeds:
        start = time.perf_counter()
        data = suite_eval_data(suite, n, seed)
        per_seed[str(seed)] = {fam: family_result(frames, estimators, checked, models) for fam, frames in data.items()}
        log(f"seed {seed}: {len(data)} families x {n} frames in {time.perf_counter() - start:.0f} s")
    families: dict[str, dict[str, Any]] = {}
    for fam in suite.families:
        rows = [per_seed[str(s)][fam.name] for s in seeds]
        families[fam.name] = {
            "description": fam.description,
            "methods": {
                m: {k: float(np.mean([row["methods"][m][k] for row in rows])) for k in ("r", "nrmse")}
                for m in estimators
            },
            "models": {
                m: {k: _mean(np.array([row["models"][m][k] for row in rows])) for k in rows[0]["models"][m]}
                for m in models
            },
            "margin_per_seed": {m: [row["models"][m]["margin"] for row in rows] for m in models},
        }
    if test is not None:
        for m in checked:
            in_family = checked[m].check(test.inputs)["residual"]
            for fam_result in families.values():
                limit = fam_result["models"][m]["losing_residual_median"]
                fam_result["models"][m]["test_flagged_at_losing_median"] = (
                    float(np.mean(in_family >= limit)) if np.isfinite(limit) else float("nan")
                )
    summary = {
        m: {
            "mean_margin": float(np.mean([f["models"][m]["margin"] for f in families.values()])),
            "families_below_classical": [name for name, f in families.items() if max(f["margin_per_seed"][m]) < 0],
            "families_mixed": [
                name for name, f in families.items() if min(f["margin_per_seed"][m]) < 0 <= max(f["margin_per_seed"][m])
            ],
        }
        for m in models
    }
    return {
        "suite": suite.name,
        "seeds": seeds,
        "frames_per_family": n,
        "loss_margin": LOSS_MARGIN,
        "thresholds": {m: checked[m].thresholds_ for m in checked},
        "test": None if test is None else test.source,
        "summary": summary,
        "families": families,
        "per_seed": per_seed,
    }


def markdown(result: dict[str, Any], models: list[str]) -> str:
    """Two tables: r / NRMSE of every method with each model's margin, then each model's flag figures."""
    methods = [*CLASSICAL, *models]
    families = result["families"]
    seeds = ", ".join(str(s) for s in result["seeds"])
    lines = [
        f"# `{result['suite']}`: {result['frames_per_family']} frames a family at each of the seeds {seeds}",
        "",
        f"`{result['command']}`",
        "",
        "r mean / NRMSE, mean of the seeds (best r of each row in bold); margin: the model's r minus the best "
        "classical rule's, at each seed.",
        "",
        "| family | " + " | ".join(methods) + " | " + " | ".join(f"{m}: margin per seed" for m in models) + " |",
        "|---|" + "---:|" * (len(methods) + len(models)),
    ]
    for name, fam in families.items():
        best = max(fam["methods"][m]["r"] for m in methods)
        cells = []
        for m in methods:
            r, e = fam["methods"][m]["r"], fam["methods"][m]["nrmse"]
            cells.append(f"**{r:.3f} / {e:.3f}**" if r == best else f"{r:.3f} / {e:.3f}")
        cells += [" ".join(f"{x:+.3f}" for x in fam["margin_per_seed"][m]) for m in models]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    means = [np.mean([f["methods"][m]["r"] for f in families.values()]) for m in methods]
    margins = [f"{result['summary'][m]['mean_margin']:+.3f}" for m in models]
    lines += ["| **mean over families** | " + " | ".join([f"{v:.3f}" for v in means] + margins) + " |", ""]
    for m in models:
        s = result["summary"][m]
        lines.append(
            f"- `{m}` below the best classical rule at every seed: {', '.join(s['families_below_classical']) or 'none'}"
            f"; at some seeds: {', '.join(s['families_mixed']) or 'none'}."
        )
    flagging = [m for m in models if m in result["thresholds"]]  # the models with a readings residual
    lines += [
        "",
        "The readings-residual flag (card thresholds), mean of the seeds: flagged, the share of frames above a "
        f"threshold; losing, the share of frames the model answers more than {result['loss_margin']} below the "
        "best classical rule (per-frame r), and of those the share flagged and the 90th percentile of their "
        "residual over the residual threshold (below 1: not flagged); guarded, r with the intersection rule on "
        "flagged frames; half caught costs: the share of the training distribution's test frames "
        f"({result.get('test') or 'not measured'}) that a residual threshold low enough to flag half of the losing "
        "frames would flag too.",
        "",
        "| family | "
        + " | ".join(
            f"{m}: flagged, losing, losing flagged, p90 / threshold, guarded, half caught costs" for m in flagging
        )
        + " |",
        "|---|" + "---:|" * len(flagging),
    ]

    def pct(value: float) -> str:
        return f"{100 * value:.1f} %" if np.isfinite(value) else "-"

    for name, fam in families.items():
        cells = []
        for m in flagging:
            f = fam["models"][m]
            ratio = f["losing_residual_over_threshold_p90"]
            cost = pct(f.get("test_flagged_at_losing_median", float("nan")))
            cells.append(
                f"{pct(f['flagged_share'])}, {pct(f['losing_share'])}, {pct(f['losing_flagged_share'])}, "
                f"{ratio:.2f}, {f['r_guarded']:.3f}, {cost}".replace("nan", "-")
            )
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def report(result: dict[str, Any], table: str, json_path: str | None) -> None:
    """Print the table; with ``json_path``, write the result there and the table beside it (.md)."""
    print(table)
    if json_path:
        atomic_write_json(json_path, result)
        atomic_write_text(Path(json_path).with_suffix(".md"), table)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "models",
        nargs="*",
        default=["strips16", "strips16_small"],
        help="shipped model names or paths of .onnx models with their .json card beside them (a run's export)",
    )
    parser.add_argument("--suite", default="strips16_unseen")
    parser.add_argument("--seeds", type=int, nargs="+", default=[5151, 6262])
    parser.add_argument("--n", type=int, default=600, help="frames per family and seed")
    parser.add_argument("--test", help="frames of the models' training distribution (e.g. data/mixed-test)")
    parser.add_argument("--json", help="write the result here, and the Markdown table beside it (.md)")
    args = parser.parse_args(argv)
    test = get_task("strips").load_eval_data(args.test) if args.test else None
    result = evaluate(load_suite(args.suite), args.models, args.n, args.seeds, test)
    result["command"] = "python scripts/strips_unseen.py " + " ".join(argv if argv is not None else sys.argv[1:])
    report(result, markdown(result, args.models), args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
