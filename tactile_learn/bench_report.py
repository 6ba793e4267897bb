"""Markdown tables and Pareto plots of benchmark results."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from synth.io import atomic_open
from tactile_learn.bench import ERROR_METRIC

__all__ = ["markdown", "pareto_plot", "suite_markdown"]

#: metrics shown in the table per task (the first is the Pareto plot's error axis)
TABLE_METRICS = {
    "strips": ("nrmse", "pearson_r_mean", "pearson_r_median", "peak_err_mm_median"),
    "thermal": ("accuracy", "accuracy_by_duration"),
    "fsr": ("loc_err_mm_median", "loc_err_mm_p95", "force_accuracy", "detect_accuracy"),
    "capacitive": ("iou_mean", "centroid_err_mm_median", "orientation_err_deg_median", "separation_rate"),
}


def _fmt(value: Any) -> str:
    if isinstance(value, dict):
        return ", ".join(f"{k}: {_fmt(v)}" for k, v in value.items())
    if isinstance(value, float):
        return f"{value:.4g}"
    return "-" if value is None else str(value)


def markdown(result: dict[str, Any]) -> str:
    """A Markdown table of one task's benchmark (or the simulator's)."""
    if result["task"] == "simulator":
        lines = ["| scene | task | samples/s (1 process) |", "|---|---|---:|"]
        lines += [f"| {r['scene']} | {r['task']} | {r['samples_per_s']:,.0f} |" for r in result["scenes"]]
        g = result["generation"]
        lines.append("")
        lines.append(
            f"Generation of {g['n']:,} `{g['scene']}` samples with {g['workers']} workers: {g['seconds']:.1f} s "
            f"({g['samples_per_s']:,.0f} samples/s), peak RSS {g['peak_rss_mib_main']:.0f} MiB (main), "
            f"{g['peak_rss_mib_worker']:.0f} MiB (largest worker)."
        )
        return "\n".join(lines) + "\n"
    keys = TABLE_METRICS[result["task"]]
    head = ["method", "kind", "backend", *keys, "p50 us (b1)", "p99 us (b1)", "frames/s (b1024)"]
    lines = [
        f"**{result['task']}** on `{result['scene']}`, {result['n_frames']} held-out frames",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * 3 + "---:|" * (len(keys) + 3),
    ]
    for m in result["methods"]:
        cells = [m["name"], m["kind"], m["backend"], *(_fmt(m["metrics"].get(k)) for k in keys)]
        cells += [
            f"{m['latency_us_p50_b1']:,.1f}",
            f"{m['latency_us_p99_b1']:,.1f}",
            f"{m['throughput_fps_b1024']:,.0f}",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    reference = result.get("reference_metrics")
    if reference:
        lines += ["", "Reference (independent of the method): " + _fmt(reference)]
    ratios = {k: v for k, v in result.get("ratios", {}).items() if isinstance(v, dict)}
    if ratios:
        lines += [
            "",
            f"Relative to the paper's `{result['ratios']['reference']}` and to the most accurate classical "
            f"method, `{result['ratios'].get('best_classical', '-')}` (error: {result['ratios']['error_metric']}):",
            "",
        ]
        lines += [
            "| learned | error ratio | latency ratio (b1) | throughput ratio (b1024) | error ratio (best) "
            "| latency ratio (best) |",
            "|---|---:|---:|---:|---:|---:|",
        ]
        for name, r in ratios.items():
            lines.append(
                f"| {name} | {_fmt(r['error_ratio'])} | {_fmt(r['latency_ratio'])} | {_fmt(r['throughput_ratio'])} "
                f"| {_fmt(r.get('error_ratio_best'))} | {_fmt(r.get('latency_ratio_best'))} |"
            )
    return "\n".join(lines) + "\n"


def suite_markdown(result: dict[str, Any]) -> str:
    """Per-family table of a suite benchmark: the primary metric and the error metric of every
    method side by side, the best classical method per family, and each learned method's margin."""
    from tactile_learn.tasks import get_task

    primary, higher_better = get_task(result["task"]).primary_metric
    error, _ = ERROR_METRIC[result["task"]]
    methods = result["methods"]
    head = ["family", *(f"{m['name']} {primary} / {error}" for m in methods), "best classical"]
    lines = [
        f"**{result['task']}** on suite `{result['suite']}` (seed {result['seed']}), "
        f"frames per family: {', '.join(str(v) for v in sorted(set(result['n_frames_per_family'].values())))}",
        "",
        "| " + " | ".join(head) + " |",
        "|---|" + "---:|" * len(methods) + "---|",
    ]
    classical = [m for m in methods if m["kind"] == "classical"]
    rows = [*result["families"], "mean_over_families"]
    for family in rows:

        def metrics(m: dict[str, Any], fam: str = family) -> dict[str, Any]:
            out: dict[str, Any] = m["mean_over_families"] if fam == "mean_over_families" else m["families"][fam]
            return out

        cells = [f"**{family}**" if family == "mean_over_families" else family]
        cells += [f"{_fmt(metrics(m).get(primary))} / {_fmt(metrics(m).get(error))}" for m in methods]
        if classical:
            best = (max if higher_better else min)(classical, key=lambda m: float(metrics(m).get(primary, 0.0)))
            cells.append(best["name"])
        else:
            cells.append("-")
        lines.append("| " + " | ".join(cells) + " |")
    if classical:
        lines += ["", f"Margin of each learned method over the best classical method per family ({primary}):", ""]
        for m in methods:
            if m["kind"] != "learned":
                continue
            margins = {}
            for family in result["families"]:
                best_value = (max if higher_better else min)(float(c["families"][family][primary]) for c in classical)
                value = float(m["families"][family][primary])
                margins[family] = value - best_value if higher_better else best_value - value
            worst = min(margins, key=lambda k: margins[k])
            lines.append(
                f"- {m['name']}: mean margin {sum(margins.values()) / len(margins):+.3f}, "
                f"smallest {margins[worst]:+.3f} ({worst}), families beaten {sum(v > 0 for v in margins.values())}"
                f"/{len(margins)}"
            )
    lines += ["", "| method | backend | p50 us (b1) | p99 us (b1) | frames/s (b1024) |", "|---|---|---:|---:|---:|"]
    for m in methods:
        lines.append(
            f"| {m['name']} | {m['backend']} | {m['latency_us_p50_b1']:,.1f} | {m['latency_us_p99_b1']:,.1f} "
            f"| {m['throughput_fps_b1024']:,.0f} |"
        )
    return "\n".join(lines) + "\n"


#: marker per backend in the Pareto plot (others: a diamond)
_BACKEND_MARKERS = {"numpy": "o", "onnxruntime-1t": "s", "onnxruntime-2t": "P", "torch-eager-1t": "^"}


def pareto_plot(results: list[dict[str, Any]], path: str | Path) -> bool:
    """Error against latency (log axis), one panel per task, one labelled marker per method/backend."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # plotting is an optional extra
        return False
    tasks = [r for r in results if r["task"] in ERROR_METRIC and r["methods"]]
    if not tasks:
        return False
    fig, axes = plt.subplots(1, len(tasks), figsize=(5.4 * len(tasks), 4.6), squeeze=False)
    colours = [plt.get_cmap("tab10")(i) for i in range(10)]
    for ax, result in zip(axes[0], tasks, strict=True):
        metric, lower_better = ERROR_METRIC[result["task"]]
        label = metric if lower_better else f"1 - {metric}"
        # one colour per method, one marker per backend, named in a legend: backends of one model
        # sit at the same error, so labels beside the markers would overlap
        names = list(dict.fromkeys(m["name"] for m in result["methods"]))
        for m in result["methods"]:
            value = float(m["metrics"][metric])
            error = value if lower_better else 1.0 - value
            ax.scatter(
                m["latency_us_p50_b1"],
                error,
                marker=_BACKEND_MARKERS.get(m["backend"], "D"),
                color=colours[names.index(m["name"]) % len(colours)],
                s=48,
                label=f"{m['name']} [{m['backend']}]",
                edgecolors="black" if m["kind"] == "learned" else "none",
                linewidths=0.6,
            )
        ax.set_xscale("log")
        ax.set(
            xlabel="median latency per frame, batch 1 (us)",
            ylabel=f"{label} (lower is better)",
            title=f"{result['task']} ({result['scene']})",
        )
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, frameon=False)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    return True


def save_figure(fig: Any, path: str | Path, dpi: int = 100) -> None:
    """Write a matplotlib figure as PNG atomically, and close it."""
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    plt.close(fig)
    with atomic_open(path, "wb") as handle:
        handle.write(buffer.getvalue())
