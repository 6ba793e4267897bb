"""Accuracy per microsecond for the 16 x 16 strip array: every method's accuracy on the two-sphere
test set and on each family of the out-of-distribution suite, against its batch-1 latency, from one
run; the Pareto front (no other method both faster and more accurate), the issue-12 floors of every
learned model, a JSON file, a markdown table and a plot.

Latency: interleaved rounds (every method sees the same machine load), median per call of
``predict`` (input checks included) and, for ONNX models, of the bare onnxruntime session (1 thread);
the load average before and after is recorded (floors are read on a quiet machine, load < 1).

    python scripts/strips_pareto.py --models models/strips16.onnx models/strips16_small.onnx \\
        --two-spheres data/strips16-test --json results/strips_pareto.json
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from synth.dataset import simulate_shard
from synth.io import atomic_write_json, atomic_write_text
from synth.scene import load_scene
from synth.suite import load_suite
from tactile_learn.bench import BENCH_SEED
from tactile_learn.methods import resolve_method
from tactile_learn.provenance import portable_path
from tactile_learn.suites import evaluate_suite, suite_eval_data
from tactile_learn.tasks import get_task
from tactile_learn.timing import interleaved_times, summary_us, timed

CLASSICAL = ("intersection", "projection")
#: issue 12's floors for the default model
MARGIN_FLOOR = 0.05
TWO_SPHERE_FLOOR = 0.96


def pareto_front(points: dict[str, tuple[float, float]]) -> list[str]:
    """Names whose (latency, r) no other point beats: not slower and not less accurate, one strictly."""
    front = []
    for name, (lat, r) in points.items():
        others = [point for other, point in points.items() if other != name]
        dominated = any((lat2 <= lat and r2 >= r) and (lat2 < lat or r2 > r) for lat2, r2 in others)
        if not dominated:
            front.append(name)
    return sorted(front, key=lambda k: points[k][0])


def floors(families: dict[str, dict[str, Any]], model: str, two_sphere_r: float) -> dict[str, Any]:
    """Issue 12: beats the best classical method on every family, by >= 0.05 r on average."""
    margins = {}
    for family, by_method in families.items():
        best = max(by_method[c]["pearson_r_mean"] for c in CLASSICAL)
        margins[family] = by_method[model]["pearson_r_mean"] - best
    mean_margin = float(np.mean(list(margins.values())))
    return {
        "margin_per_family": margins,
        "families_below_classical": [f for f, m in margins.items() if m <= 0],
        "mean_margin": mean_margin,
        "beats_classical_on_every_family": all(m > 0 for m in margins.values()),
        "mean_margin_at_least_0.05": mean_margin >= MARGIN_FLOOR,
        "two_sphere_r": two_sphere_r,
        "two_sphere_r_at_least_0.96": two_sphere_r >= TWO_SPHERE_FLOOR,
    }


def _warm_up(call: Any, readings: np.ndarray, n: int = 20) -> float:
    """Mean seconds of ``n`` batch-1 calls (the first ones: sessions and caches are built)."""
    _, seconds = timed(lambda: [call(readings[i : i + 1]) for i in range(n)])
    return seconds / n


def latencies(methods: dict[str, Any], rounds: int, per_round: int) -> dict[str, dict[str, float]]:
    """Median and p90 per call at batch 1, ``predict`` and (ONNX) the bare session, interleaved."""
    readings = simulate_shard(load_scene("strips16"), BENCH_SEED, 0, 512)["readings"].astype(np.float32)
    calls: dict[str, Any] = {}
    for name, est in methods.items():
        calls[f"{name}|predict"] = est.predict
        session = getattr(est, "session_", None) if hasattr(est, "card_") else None
        if session is not None:
            input_name, output_name = est.card_["inputs"][0]["name"], est.card_["outputs"][0]["name"]
            calls[f"{name}|session"] = lambda x, s=session, i=input_name, o=output_name: s.run([o], {i: x})
    # warm-up (sessions, caches); a slow method (the projection's iterative solver: tens of ms a call)
    # gets one call per round
    warm = {key: _warm_up(call, readings) for key, call in calls.items()}
    repeats = {key: per_round if seconds < 2e-3 else 1 for key, seconds in warm.items()}
    times = interleaved_times(calls, readings, rounds=rounds, per_round=repeats, warmup=0)
    out: dict[str, dict[str, float]] = {}
    for key, values in times.items():
        name, kind = key.split("|")
        summary = summary_us(values)
        out.setdefault(name, {})[f"{kind}_median_us"] = summary["median_us"]
        out[name][f"{kind}_p90_us"] = summary["p90_us"]
    return out


def plot(result: dict[str, Any], path: Path) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for name, m in result["methods"].items():
        lat = m["latency"]["predict_median_us"]
        for ax, key in zip(axes, ("pearson_r_mean", "nrmse"), strict=True):
            for label, value, marker in (
                ("two spheres", m["two_spheres"][key], "o"),
                ("ood mean", m["ood_mean"][key], "s"),
            ):
                ax.scatter(lat, value, marker=marker, color="C0" if label == "two spheres" else "C1")
                ax.annotate(f"{name}", (lat, value), fontsize=7, xytext=(3, 3), textcoords="offset points")
    for ax, key in zip(axes, ("pearson_r_mean", "nrmse"), strict=True):
        for label, color, part in (("two spheres", "C0", "two_spheres"), ("ood mean over families", "C1", "ood_mean")):
            front = result["pareto_front"][part]
            xs = [result["methods"][n]["latency"]["predict_median_us"] for n in front]
            ys = [result["methods"][n][part][key] for n in front]
            ax.plot(xs, ys, color=color, label=f"{label} (Pareto front)")
        # NRMSE on a log axis: one diverging frame of the intersection rule makes its mean huge
        ax.set(xlabel="batch-1 latency, predict (us, median)", ylabel=key, xscale="log")
        if key == "nrmse":
            ax.set_yscale("log")
        ax.legend(fontsize=7)
    axes[0].set_title("r (higher is better)")
    axes[1].set_title("NRMSE (lower is better)")
    fig.suptitle(f"strips16: accuracy per microsecond (load {result['load_average_1min'][0]:.1f})", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def _cell(metrics: dict[str, Any]) -> str:
    return f"{metrics['pearson_r_mean']:.3f} / {metrics['nrmse']:.3f}"


def markdown(result: dict[str, Any]) -> str:
    names = list(result["methods"])
    lines = ["| family | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    for family in result["families"]:
        cells = [_cell(result["methods"][n]["ood"][family]) for n in names]
        lines.append(f"| {family} | " + " | ".join(cells) + " |")
    for label, part in (("ood mean", "ood_mean"), ("two spheres", "two_spheres")):
        cells = [_cell(result["methods"][n][part]) for n in names]
        lines.append(f"| **{label}** | " + " | ".join(cells) + " |")
    cells = [f"{result['methods'][n]['latency']['predict_median_us']:.0f}" for n in names]
    lines.append("| predict, batch 1 (us, median) | " + " | ".join(cells) + " |")
    cells = [f"{result['methods'][n]['latency'].get('session_median_us', float('nan')):.0f}" for n in names]
    lines.append("| onnxruntime session, batch 1 (us) | " + " | ".join(cells) + " |")
    lines.append("")
    lines.append(f"r / NRMSE per cell; load average (1 min) before / after: {result['load_average_1min']}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--models", nargs="+", default=["models/strips16.onnx", "models/strips16_spheres.onnx"])
    parser.add_argument("--two-spheres", default="data/strips16-test", help="two-sphere test set (strips16 scene)")
    parser.add_argument("--suite", default="strips16_ood")
    parser.add_argument("--n", type=int, default=1000, help="frames per family")
    parser.add_argument("--rounds", type=int, default=200)
    parser.add_argument("--per-round", type=int, default=20)
    parser.add_argument("--json", default="results/strips_pareto.json")
    args = parser.parse_args(argv)
    task = get_task("strips")
    suite = load_suite(args.suite)
    ood = suite_eval_data(suite, args.n, BENCH_SEED)
    two = task.load_eval_data(args.two_spheres)
    methods: dict[str, Any] = {c: resolve_method("strips", c, suite.base) for c in CLASSICAL}
    for model in args.models:
        methods[Path(model).stem] = resolve_method("strips", model, suite.base, threads=1)
    result: dict[str, Any] = {"suite": suite.name, "seed": BENCH_SEED, "families": list(ood), "methods": {}}
    for name, est in methods.items():
        report = evaluate_suite(est, ood, "strips")
        sphere_est = resolve_method("strips", name if name in CLASSICAL else str(est.path), two.scene, threads=1)
        result["methods"][name] = {
            "ood": report["families"],
            "ood_mean": report["mean_over_families"],
            "two_spheres": task.evaluate(sphere_est, two),
        }
        print(f"{name}: ood r {report['mean_over_families']['pearson_r_mean']:.4f}", flush=True)
    load_before = os.getloadavg()
    timing = latencies(methods, args.rounds, args.per_round)
    load_after = os.getloadavg()
    result["load_average_1min"] = [round(load_before[0], 2), round(load_after[0], 2)]
    for name, t in timing.items():
        result["methods"][name]["latency"] = t
    families = {f: {n: result["methods"][n]["ood"][f] for n in methods} for f in ood}
    result["floors"] = {
        n: floors(families, n, result["methods"][n]["two_spheres"]["pearson_r_mean"])
        for n in methods
        if n not in CLASSICAL
    }
    result["pareto_front"] = {
        part: pareto_front(
            {n: (m["latency"]["predict_median_us"], m[part]["pearson_r_mean"]) for n, m in result["methods"].items()}
        )
        for part in ("two_spheres", "ood_mean")
    }
    result["two_spheres_data"] = portable_path(args.two_spheres)
    result["command"] = "python scripts/strips_pareto.py " + " ".join(argv if argv is not None else sys.argv[1:])
    out = Path(args.json)
    atomic_write_json(out, result)
    table = markdown(result)
    atomic_write_text(out.with_suffix(".md"), table + "\n")
    plotted = plot(result, out.with_suffix(".png"))
    print(table)
    for name, f in result["floors"].items():
        print(
            f"{name}: below classical on {f['families_below_classical'] or 'no family'}, mean margin "
            f"{f['mean_margin']:+.4f}, two spheres r {f['two_sphere_r']:.4f}"
        )
    print(f"written {out}, {out.with_suffix('.md')}" + (f", {out.with_suffix('.png')}" if plotted else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
