"""Design sweeps: which sensor design gives the best map per wire? (generate x train x evaluate).

A sweep file (TOML) names a base scene and the design parameters to vary::

    name = "strips-design"
    base = "strips16"                 # shipped scene name or path
    mode = "grid"                     # "grid": every combination; "random": `points` draws
    points = 24                       # random mode only
    seed = 0                          # random draws and every point's data seeds derive from it

    [parameters]                      # dotted paths into the scene (its TOML layout)
    "strips.layers.cover_mm" = [0.5, 1.0, 2.0]
    "strips.readout.adc_bits" = [8, 12]
    # one key may set several paths to the same value: separate them with "+"
    "strips.geometry.n_rows+strips.geometry.n_cols" = [8, 12, 16]

    [budget]                          # per point (defaults shown)
    train = 20000                     # training frames; 0 = classical methods only
    val = 2000
    test = 2000
    epochs = 4
    size = ""                         # network size ("" = the task's smallest)
    methods = ["intersection", "projection"]   # classical methods evaluated beside the network

Every point is one task on a Dask cluster (:mod:`tactile_learn.cluster`): it writes its scene, its
datasets, its run and its exported model under ``OUT/points/<id>/`` and finishes by writing
``result.json`` (atomically, last). A point whose ``result.json`` exists is not recomputed, so an
interrupted sweep resumes where it stopped; the point's id is a digest of its parameter values,
stable whatever the order of the grid. ``OUT/sweep.json`` holds every point's config and metrics,
``OUT/sweep.md`` the table and the recommended design per wire budget, ``OUT/sweep.png`` the plots
(error against wire count and against latency).
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from synth.config import dumps_toml
from synth.errors import ConfigError, TactileError
from synth.io import atomic_write_json, atomic_write_text
from synth.scene import Scene, load_scene, parse_scene, read_toml

__all__ = ["Budget", "SweepConfig", "load_sweep", "run_point", "run_sweep", "sweep_points", "wire_count"]

RESULT = "result.json"
_TOP_KEYS = ("name", "base", "mode", "points", "seed", "parameters", "budget", "description", "rank_by")
# what the recommendation may rank designs by: +1 higher is better, -1 lower is better. r and NRMSE
# are computed on each design's own cells (a coarse array scores high r: one cell holds a contact);
# the peak-position error in mm compares arrays of different pitch and strip count on one scale.
RANK_METRICS = {"pearson_r_mean": 1, "nrmse": -1, "peak_err_mm_median": -1, "peak_err_mm_mean": -1}


@dataclass(frozen=True)
class Budget:
    train: int = 20000
    val: int = 2000
    test: int = 2000
    epochs: int = 4
    size: str = ""
    methods: tuple[str, ...] = ("intersection", "projection")


@dataclass(frozen=True)
class SweepConfig:
    name: str
    base: Scene
    parameters: dict[str, tuple[Any, ...]]
    mode: str = "grid"
    points: int = 0
    seed: int = 0
    budget: Budget = field(default_factory=Budget)
    description: str = ""
    rank_by: str = "pearson_r_mean"


def _budget(data: Any, source: str) -> Budget:
    if not isinstance(data, Mapping):
        raise ConfigError(f"{source}: budget: expected a table")
    known = {f for f in Budget.__dataclass_fields__}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ConfigError(f"{source}: budget.{unknown[0]}: unknown key (known: {', '.join(sorted(known))})")
    values: dict[str, Any] = {}
    for key in ("train", "val", "test", "epochs"):
        if key in data:
            value = data[key]
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ConfigError(f"{source}: budget.{key}: expected a non-negative integer, got {value!r}")
            values[key] = value
    if "size" in data:
        if not isinstance(data["size"], str):
            raise ConfigError(f"{source}: budget.size: expected a string")
        values["size"] = data["size"]
    if "methods" in data:
        methods = data["methods"]
        if not isinstance(methods, list) or not all(isinstance(m, str) for m in methods):
            raise ConfigError(f"{source}: budget.methods: expected a list of method names")
        values["methods"] = tuple(methods)
    budget = Budget(**values)
    if budget.train and (budget.val < 1 or budget.epochs < 1):
        raise ConfigError(f"{source}: budget: training needs val >= 1 and epochs >= 1")
    if budget.test < 1:
        raise ConfigError(f"{source}: budget.test: at least one test frame is needed")
    return budget


def parse_sweep(data: Mapping[str, Any], source: str = "<sweep>") -> SweepConfig:
    """Validate a sweep given as a dict (the parsed TOML); every point's scene is checked here, so a
    bad value fails before any work starts."""
    unknown = sorted(set(data) - set(_TOP_KEYS))
    if unknown:
        raise ConfigError(f"{source}: {unknown[0]}: unknown key (known keys: {', '.join(_TOP_KEYS)})")
    if "base" not in data:
        raise ConfigError(f"{source}: base: name the scene the sweep varies")
    base = load_scene(data["base"])
    mode = data.get("mode", "grid")
    if mode not in ("grid", "random"):
        raise ConfigError(f"{source}: mode: {mode!r} is not 'grid' or 'random'")
    params = data.get("parameters")
    if not isinstance(params, Mapping) or not params:
        raise ConfigError(f"{source}: parameters: expected a table of dotted scene paths and their values")
    parameters: dict[str, tuple[Any, ...]] = {}
    for key, values in params.items():
        if not isinstance(values, list) or not values:
            raise ConfigError(f"{source}: parameters.{key}: expected a non-empty list of values")
        parameters[str(key)] = tuple(values)
    points, seed = data.get("points", 0), data.get("seed", 0)
    for name, value in (("points", points), ("seed", seed)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ConfigError(f"{source}: {name}: expected a non-negative integer, got {value!r}")
    if mode == "random" and points < 1:
        raise ConfigError(f"{source}: points: random mode needs points >= 1")
    rank_by = data.get("rank_by", "pearson_r_mean")
    if rank_by not in RANK_METRICS:
        raise ConfigError(f"{source}: rank_by: {rank_by!r} is not one of {', '.join(RANK_METRICS)}")
    config = SweepConfig(
        name=str(data.get("name", Path(source).stem)),
        rank_by=rank_by,
        base=base,
        parameters=parameters,
        mode=mode,
        points=points,
        seed=seed,
        budget=_budget(data.get("budget", {}), source),
        description=str(data.get("description", "")),
    )
    for values in sweep_points(config):
        try:
            point_scene(config.base, values)
        except ConfigError as exc:
            raise ConfigError(f"{source}: point {values}: {exc}") from None
    return config


def load_sweep(name_or_path: str | Path) -> SweepConfig:
    """A shipped sweep by name (``tactile_learn/sweeps/<name>.toml``) or any sweep file by path."""
    data, source = read_toml(name_or_path, "sweeps", "sweep", package="tactile_learn")
    return parse_sweep(data, source)


def sweep_points(config: SweepConfig) -> list[dict[str, Any]]:
    """The design points: every combination (grid) or ``points`` distinct draws (random)."""
    keys = list(config.parameters)
    grid = [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*config.parameters.values())]
    if config.mode == "grid":
        return grid
    rng = np.random.default_rng(config.seed)
    picked = rng.choice(len(grid), size=min(config.points, len(grid)), replace=False)
    return [grid[i] for i in sorted(picked)]


def _set_path(data: dict[str, Any], path: str, value: Any) -> None:
    keys = path.split(".")
    node = data
    for key in keys[:-1]:
        child = node.get(key)
        if not isinstance(child, dict):
            raise ConfigError(f"{path}: {key!r} is not a table of the scene")
        node = child
    node[keys[-1]] = copy.deepcopy(value)


def point_scene(base: Scene, values: Mapping[str, Any]) -> Scene:
    """The base scene with the point's values set (``a+b`` keys set both paths)."""
    data = base.to_dict()
    for key, value in values.items():
        for path in key.split("+"):
            _set_path(data, path.strip(), value)
    data["name"] = f"{base.name}@{point_id(values)}"
    return parse_scene(data, data["name"])


def point_id(values: Mapping[str, Any]) -> str:
    blob = json.dumps(dict(sorted(values.items())), sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:10]


def wire_count(scene: Scene) -> int:
    """Wires a design needs to its readout: one per strip (per read end for two-ended strips)."""
    wires = getattr(scene.sensor, "wire_count", None)
    if callable(wires):
        return int(wires())
    g = scene.sensor.geometry
    return int(g.n_rows + g.n_cols)


def _seeds(config_seed: int, values: Mapping[str, Any]) -> dict[str, int]:
    """Data seeds of a point: distinct for train, val and test, and from point to point."""
    entropy = int(point_id(values), 16)
    seq = np.random.SeedSequence([config_seed, entropy])
    train, val, test = (int(s.generate_state(1)[0]) for s in seq.spawn(3))
    return {"train": train, "val": val, "test": test}


def run_point(
    values: dict[str, Any], base: dict[str, Any], budget: dict[str, Any], seed: int, folder: str
) -> dict[str, Any]:
    """One design point, start to end (what a cluster worker runs): generate, train, export,
    evaluate; returns and writes ``folder/result.json``. Failures are recorded, not raised."""
    import torch

    from synth.dataset import generate
    from tactile_learn.methods import resolve_method
    from tactile_learn.tasks import get_task
    from tactile_learn.tasks.base import readable_frames
    from tactile_learn.timing import time_predict

    torch.set_num_threads(1)  # one core per worker: the cluster's processes share the machine
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    result: dict[str, Any] = {"id": point_id(values), "values": values}
    try:
        scene = point_scene(parse_scene(base, "base"), values)
        bud = Budget(**{**budget, "methods": tuple(budget["methods"])})
        seeds = _seeds(seed, values)
        task = get_task(scene.task)
        atomic_write_text(out / "scene.toml", dumps_toml(scene.to_dict()))
        result.update(scene=scene.to_dict(), scene_digest=scene.digest, wires=wire_count(scene), seeds=seeds)
        generate(scene, bud.test, seeds["test"], out / "test")
        data, unreadable = readable_frames(task, task.load_eval_data(out / "test"))
        result["unreadable"] = unreadable
        methods: dict[str, Any] = {name: resolve_method(scene.task, name, scene) for name in bud.methods}
        if bud.train:
            from tactile_learn.export import export
            from tactile_learn.train import TrainConfig, train

            generate(scene, bud.train, seeds["train"], out / "train")
            generate(scene, bud.val, seeds["val"], out / "val")
            config = TrainConfig(
                task=scene.task,
                data=str(out / "train"),
                val=str(out / "val"),
                out=str(out / "run"),
                size=bud.size,
                epochs=bud.epochs,
                threads=1,
                seed=seed,
            )
            resume = (out / "run" / "checkpoint.pt").is_file()
            if not (out / "run" / "model.pt").is_file():
                trained = train(config, resume=resume, progress=False)
            else:
                trained = json.loads((out / "run" / "metrics.json").read_text())
            result["train_seconds"] = trained["train_seconds"]
            export(out / "run", out / "model.onnx", name=f"sweep-{result['id']}")
            methods["learned"] = resolve_method(scene.task, str(out / "model.onnx"), scene)
        rows = {}
        for name, est in methods.items():
            metrics = task.evaluate(est, data)
            timing = time_predict(est.predict, task.latency_inputs(data), repeats=200, budget_s=1.0)
            rows[name] = {
                "kind": est.kind,
                "backend": est.backend,
                **{k: v for k, v in metrics.items() if isinstance(v, (int, float))},
                "latency_us_p50_b1": timing["latency_us_p50_b1"],
            }
        result["methods"] = rows
        result["status"] = "ok"
    except TactileError as exc:
        result.update(status="failed", error=f"{type(exc).__name__}: {exc}")
    except Exception as exc:  # a worker must report, not take the sweep down
        result.update(status="failed", error=f"{type(exc).__name__}: {exc}", traceback=traceback.format_exc())
    result["seconds"] = time.perf_counter() - started
    atomic_write_json(out / RESULT, result)
    return result


def run_sweep(
    config: SweepConfig,
    out: str | Path,
    *,
    scheduler: str | None = None,
    workers: int = 2,
    report: bool = True,
    progress: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Run every point not yet finished on a Dask cluster; write ``sweep.json``/``.md``/``.png``."""
    from concurrent.futures import as_completed

    from tactile_learn.cluster import cluster_client, performance_report

    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    points = sweep_points(config)
    budget = {**config.budget.__dict__, "methods": list(config.budget.methods)}
    base = config.base.to_dict()
    results: dict[str, dict[str, Any]] = {}
    todo = []
    for values in points:
        pid = point_id(values)
        done = folder / "points" / pid / RESULT
        if done.is_file():
            previous = json.loads(done.read_text())
            if previous.get("status") == "ok":
                results[pid] = previous
                continue
        todo.append(values)
    started = time.perf_counter()
    if todo:
        report_path = folder / "dask-report.html" if report else None
        with cluster_client(scheduler, workers=workers) as client, performance_report(report_path):
            executor = client.get_executor(pure=False)
            futures = [
                executor.submit(run_point, values, base, budget, config.seed, str(folder / "points" / point_id(values)))
                for values in todo
            ]
            for future in as_completed(futures):
                res = future.result()
                results[res["id"]] = res
                if progress:
                    progress(res)
    finished = [results[point_id(v)] for v in points if point_id(v) in results]
    summary: dict[str, Any] = {
        "sweep": config.name,
        "base": config.base.name,
        "mode": config.mode,
        "parameters": {k: list(v) for k, v in config.parameters.items()},
        "budget": budget,
        "n_points": len(points),
        "computed_now": len(todo),
        "seconds": time.perf_counter() - started,
        "points": finished,
        "rank_by": config.rank_by,
        "recommended": recommend(finished, config.rank_by),
    }
    atomic_write_json(folder / "sweep.json", summary)
    atomic_write_text(folder / "sweep.md", markdown(summary))
    plot(summary, folder / "sweep.png")
    return summary


def _score(point: Mapping[str, Any], row: Mapping[str, Any], rank_by: str) -> float:
    """Higher is better. A frame the design cannot read (a saturated ADC) gives no map: r counts it
    as 0 (scaled by the readable share), an error is divided by that share."""
    readable = 1.0 - _unreadable(point)
    value = float(row.get(rank_by, float("nan")))
    if value != value:  # a method without this metric never wins
        return float("-inf")
    return value * readable if RANK_METRICS[rank_by] > 0 else -value / max(readable, 1e-9)


def _best_method(point: dict[str, Any], rank_by: str = "pearson_r_mean") -> tuple[str, dict[str, Any]]:
    """The point's best method by ``rank_by`` (only called on finished points, which have methods)."""
    rows = point["methods"]
    name = max(rows, key=lambda m: _score(point, rows[m], rank_by))
    return name, rows[name]


def recommend(points: Sequence[dict[str, Any]], rank_by: str = "pearson_r_mean") -> list[dict[str, Any]]:
    """Per wire budget (each wire count the sweep tried): the best design by ``rank_by`` that needs
    no more wires, and the method that reaches it (see :func:`_score` for unreadable frames)."""
    ok = [p for p in points if p.get("status") == "ok" and p.get("methods")]
    out = []
    for budget in sorted({int(p["wires"]) for p in ok}):
        candidates = [p for p in ok if p["wires"] <= budget]
        best = max(candidates, key=lambda p: _score(p, _best_method(p, rank_by)[1], rank_by))
        method, row = _best_method(best, rank_by)
        out.append(
            {
                "wire_budget": budget,
                "point": best["id"],
                "values": best["values"],
                "wires": best["wires"],
                "method": method,
                "rank_by": rank_by,
                "pearson_r_mean": row["pearson_r_mean"],
                "pearson_r_effective": row["pearson_r_mean"] * (1.0 - _unreadable(best)),
                "unreadable_share": _unreadable(best),
                "nrmse": row.get("nrmse"),
                "peak_err_mm_median": row.get("peak_err_mm_median"),
                "latency_us_p50_b1": row["latency_us_p50_b1"],
            }
        )
    return out


def _unreadable(point: Mapping[str, Any]) -> float:
    return float(point.get("unreadable", {}).get("share", 0.0))


def markdown(summary: dict[str, Any]) -> str:
    keys = list(summary["parameters"])
    lines = [
        f"# Sweep {summary['sweep']} (base {summary['base']}, {summary['n_points']} points, {summary['mode']})",
        "",
        "r and NRMSE over the frames the design can read; saturated: the share of test frames whose"
        " readings reach the ADC's full scale (no map; counted as r = 0 in the recommendation).",
        "",
        "| point | " + " | ".join(keys) + " | wires | saturated | method | r mean | NRMSE | latency b1 (us) |",
        "|---|" + "---|" * len(keys) + "---:|---:|---|---:|---:|---:|",
    ]
    for p in sorted(summary["points"], key=lambda q: (q.get("wires", 0), q["id"])):
        vals = " | ".join(str(p["values"].get(k)) for k in keys)
        if p.get("status") != "ok":
            lines.append(f"| {p['id']} | {vals} | - | - | failed: {p.get('error', '')[:80]} | | | |")
            continue
        for name, row in p["methods"].items():
            lines.append(
                f"| {p['id']} | {vals} | {p['wires']} | {_unreadable(p):.1%} | {name} | "
                f"{row.get('pearson_r_mean', float('nan')):.3f} | "
                f"{row.get('nrmse', float('nan')):.3f} | {row['latency_us_p50_b1']:.0f} |"
            )
    lines += [
        "",
        "## Recommended design per wire budget",
        "",
        f"Ranked by `{summary.get('rank_by', 'pearson_r_mean')}`.",
        "",
        "| wires at most | design | method | r mean | r (saturated = 0) | NRMSE | peak error median (mm) |"
        " latency b1 (us) |",
        "|---:|---|---|---:|---:|---:|---:|---:|",
    ]
    for rec in summary["recommended"]:
        design = ", ".join(f"{k}={v}" for k, v in rec["values"].items())
        lines.append(
            f"| {rec['wire_budget']} | {design} ({rec['wires']} wires) | {rec['method']} | "
            f"{rec['pearson_r_mean']:.3f} | {rec['pearson_r_effective']:.3f} | {rec['nrmse']:.3f} | "
            f"{rec.get('peak_err_mm_median') or float('nan'):.2f} | {rec['latency_us_p50_b1']:.0f} |"
        )
    return "\n".join(lines) + "\n"


def plot(summary: dict[str, Any], path: Path) -> bool:
    """Error against wire count and against latency, one colour per method (matplotlib optional)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from tactile_learn.bench_report import save_figure
    except ImportError:
        return False
    ok = [p for p in summary["points"] if p.get("status") == "ok"]
    methods = sorted({m for p in ok for m in p["methods"]})
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for i, method in enumerate(methods):
        pts = [(p["wires"], p["methods"][method]) for p in ok if method in p["methods"]]
        wires = [w for w, _ in pts]
        err = [r.get("nrmse", np.nan) for _, r in pts]
        lat = [r["latency_us_p50_b1"] for _, r in pts]
        axes[0].scatter(wires, err, label=method, color=f"C{i}", alpha=0.8)
        axes[1].scatter(lat, err, label=method, color=f"C{i}", alpha=0.8)
    axes[0].set(xlabel="wires to the readout", ylabel="NRMSE (lower is better)", title="error against wire count")
    axes[1].set(xlabel="latency at batch 1 (us)", ylabel="NRMSE", xscale="log", title="error against latency")
    axes[0].legend()
    fig.tight_layout()
    save_figure(fig, path)
    return True
