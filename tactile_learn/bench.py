"""Run time against error: every method and backend of a task on the same held-out frames.

For each registered classical method and each shipped model of the task (onnxruntime with 1 and 2
threads, and torch eager when torch is installed and the model's weights are shipped beside it):

- the task's metrics (``task.evaluate``: the numbers ``tactile-learn eval`` prints);
- latency at batch 1: warm-up calls, then timed calls until ``repeats`` or the time budget,
  median and 99th percentile per frame (microseconds);
- throughput at batch 1024 (frames per second, median of repeats).

The ``simulator`` pseudo-task reports samples/s per scene and the peak memory of a dataset
generation. JSON schema (stable): ``{"task", "scene", "n_frames", "machine", "methods": [{"name",
"kind", "backend", "metrics", "latency_us_p50_b1", "latency_us_p99_b1", "throughput_fps_b1024"}],
"ratios": {"reference", "best_classical", "error_metric", "NAME [BACKEND]": {"error_ratio",
"latency_ratio", "throughput_ratio", "error_ratio_best", "latency_ratio_best"}}}``: ratios are learned
over classical, against the paper's method (``reference``) and the most accurate classical method of
the same run (``*_best``); the error is ``error_metric`` (for accuracies, one minus the accuracy).
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import tempfile
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from synth import __version__
from synth.dataset import generate
from synth.errors import ConfigError
from synth.io import atomic_write_json
from synth.scene import Scene, available_scenes, load_scene
from tactile_learn.estimators.base import Estimator
from tactile_learn.methods import shipped_cards
from tactile_learn.tasks import get_task
from tactile_learn.tasks.base import EvalData
from tactile_learn.timing import interleaved_times, time_predict, timed

__all__ = ["ERROR_METRIC", "bench_simulator", "bench_suite", "bench_task", "machine_info", "record_run"]

#: per task: (metric plotted as error, lower is better?) - the Pareto plot's y axis
ERROR_METRIC: dict[str, tuple[str, bool]] = {
    "strips": ("nrmse", True),
    "thermal": ("accuracy", False),
    "fsr": ("loc_err_mm_median", True),
    "capacitive": ("iou_mean", False),
}
#: the seed paper's own algorithm per task: the reference of the ratios
REFERENCE_METHOD = {"strips": "intersection", "thermal": "curve_match", "fsr": "triangulation", "capacitive": "bicubic"}
BENCH_SEED = 909_090  # held-out frames: no training or validation set uses this seed


def record_run(
    result: dict[str, Any], script: str, argv: list[str] | None, load_before: float, out: str | None
) -> None:
    """Close a benchmark script's ``result``: the 1-minute load before and after, the command that
    reproduces it (``python scripts/SCRIPT ARGS``), printed load, and the JSON at ``out`` if given
    (written atomically)."""
    result["load_average_1min"] = [load_before, os.getloadavg()[0]]
    result["command"] = f"python scripts/{script} " + " ".join(argv if argv is not None else sys.argv[1:])
    print(f"load average (1 min) before / after: {result['load_average_1min']}")
    if out:
        atomic_write_json(out, result)


def machine_info() -> dict[str, Any]:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    versions = {"tactile_learn": __version__, "numpy": np.__version__, "python": platform.python_version()}
    for module in ("scipy", "onnxruntime", "torch"):
        try:
            versions[module] = __import__(module).__version__
        except ImportError:
            continue
    return {"cpu": cpu, "cores": os.cpu_count(), "platform": sys.platform, "versions": versions}


def _bench_data(task_name: str, scene: Scene | None, n: int, data: str | None) -> EvalData:
    """Frames to benchmark on: ``data`` (with its own scene unless one is given), else a fresh
    dataset of the task's scene on a seed no training or validation set uses."""
    task = get_task(task_name)
    if data:
        return task.load_eval_data(data, scene).subset(slice(0, n))
    scene = scene or load_scene(task.default_scene)
    with tempfile.TemporaryDirectory(prefix="tl-bench-") as tmp:
        generate(scene, n, BENCH_SEED, Path(tmp) / "frames")
        frames = task.load_eval_data(Path(tmp) / "frames", scene)
        # in memory before the folder goes: memory-mapped shards would dangle
        return EvalData(
            inputs=np.array(frames.inputs),
            truth={k: np.array(v) for k, v in frames.truth.items()},
            scene=frames.scene,
            extra={k: np.array(v) for k, v in frames.extra.items()},
            source=f"{scene.name} seed {BENCH_SEED}",
        )


def _learned_variants(task_name: str, scene: Scene) -> list[tuple[str, Callable[[], Estimator]]]:
    """(label, factory) for every shipped model of the task whose scene matches: ORT 1 and 2
    threads, and torch eager when torch and the model's weights (NAME.pt) are available."""
    variants: list[tuple[str, Callable[[], Estimator]]] = []
    for name, (path, card) in sorted(shipped_cards(task_name).items()):
        if card["scene_digest"] != scene.digest and not _same_sensor(task_name, card["scene"], scene):
            continue
        for threads in (1, 2):
            variants.append((name, partial(_onnx_model, path, threads, card)))
        if "thresholds" in card.get("consistency", {}):  # the checked path: flags + fallback
            variants.append((f"{name}+check", partial(_checked_model, path)))
        weights = path.with_suffix(".pt")
        if weights.is_file() and _torch_available():
            # a routed card's weights are its own graph's: torch runs that network alone, not the route
            label = f"{name} (own graph)" if "route" in card else name
            variants.append((label, partial(_torch_model, weights, card)))
    return variants


def _same_sensor(task_name: str, card_scene: dict[str, Any], scene: Scene) -> bool:
    """A model trained on another scene of the same sensor (e.g. the general strip model, trained on
    every shape) runs on ``scene`` too."""
    from synth.scene import parse_scene

    try:
        return get_task(task_name).same_sensor(parse_scene(card_scene), scene)
    except Exception:  # a card whose scene does not parse is reported by eval, not by the benchmark
        return False


def _onnx_model(path: Path, threads: int, card: dict[str, Any]) -> Estimator:
    from tactile_learn.runtime import OnnxEstimator

    return OnnxEstimator(path, threads=threads, card=card, backend=f"onnxruntime-{threads}t").prepare()


def _checked_model(path: Path) -> Estimator:
    from tactile_learn.strips_guard import CheckedStripModel

    return CheckedStripModel(path, threads=1, backend="onnxruntime-1t").prepare()


def _torch_available() -> bool:
    try:
        import torch  # noqa: F401
    except ImportError:
        return False
    return True


def _torch_model(weights: Path, card: dict[str, Any]) -> Estimator:
    from synth.scene import parse_scene
    from tactile_learn.torch_estimator import TorchEstimator

    return TorchEstimator.from_checkpoint(weights, parse_scene(card["scene"]), threads=1, backend="torch-eager-1t")


def bench_task(
    task_name: str,
    *,
    n_frames: int | None = None,
    repeats: int = 300,
    budget_s: float = 3.0,
    scene_name: str | None = None,
    data: str | None = None,
    methods: list[str] | None = None,
    progress: Callable[[str], None] | None = None,
    reference: bool = False,
) -> dict[str, Any]:
    """Benchmark every method of ``task_name`` on the same frames (``n_frames`` samples, default
    the task's ``bench_samples``); ``reference`` adds the task's method-independent metrics."""
    task = get_task(task_name)
    n = n_frames or task.bench_samples
    frames = _bench_data(task_name, load_scene(scene_name) if scene_name else None, n, data)
    scene = frames.scene
    entries: list[tuple[str, Callable[[], Estimator]]] = [
        (name, partial(factory, scene)) for name, factory in task.classical_methods().items()
    ]
    entries += _learned_variants(task_name, scene)
    results = []
    for label, factory in entries:
        if methods and label not in methods:
            continue
        est = factory()
        if progress:
            progress(f"{task_name}: {label} [{est.backend}]")
        metrics, eval_seconds = timed(partial(task.evaluate, est, frames))
        timing = time_predict(est.predict, task.latency_inputs(frames), repeats=repeats, budget_s=budget_s)
        results.append(
            {
                "name": label,
                "kind": est.kind,
                "backend": est.backend,
                "metrics": metrics,
                "eval_seconds": eval_seconds,
                **timing,
            }
        )
    result: dict[str, Any] = {
        "task": task_name,
        "scene": scene.name,
        "scene_digest": scene.digest,
        "n_frames": len(frames),
        "machine": machine_info(),
        "methods": results,
        "ratios": ratios(task_name, results),
    }
    if reference:
        result["reference_metrics"] = task.reference_metrics(frames)
    return result


def bench_suite(
    task_name: str,
    suite_name: str,
    *,
    n_frames: int | None = None,
    repeats: int = 300,
    budget_s: float = 3.0,
    methods: list[str] | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Every method of ``task_name`` on every family of a suite (fresh frames of seed
    :data:`BENCH_SEED`): per-family metrics, their mean over families, and the latency at batch 1
    (on the first family's frames; the methods' run time does not depend on the shapes pressed)."""
    from synth.suite import load_suite
    from tactile_learn.suites import evaluate_suite, suite_eval_data

    task = get_task(task_name)
    suite = load_suite(suite_name)
    if suite.base.task != task_name:
        raise ConfigError(f"--suite: {suite.name!r} is a suite of {suite.base.task!r} scenes, not {task_name!r}")
    data = suite_eval_data(suite, n_frames, BENCH_SEED)
    scene = suite.base
    entries: list[tuple[str, Callable[[], Estimator]]] = [
        (name, partial(factory, scene)) for name, factory in task.classical_methods().items()
    ]
    # one backend per learned model: the accuracy is the same on every backend
    entries += [
        (label, f) for label, f in _learned_variants(task_name, scene) if _backend_of(f) in ("onnx-1", "checked")
    ]
    results = []
    first = next(iter(data.values()))
    for label, factory in entries:
        if methods and label not in methods:
            continue
        est = factory()
        report = evaluate_suite(est, data, task_name, progress=_prefixed(progress, label))
        timing = time_predict(est.predict, task.latency_inputs(first), repeats=repeats, budget_s=budget_s)
        results.append({"name": label, "kind": est.kind, "backend": est.backend, **report, **timing})
    return {
        "task": task_name,
        "suite": suite.name,
        "scene": scene.name,
        "seed": BENCH_SEED,
        "families": list(data),
        "n_frames_per_family": {name: len(d) for name, d in data.items()},
        "machine": machine_info(),
        "methods": results,
    }


def _prefixed(progress: Callable[[str], None] | None, prefix: str) -> Callable[[str], None] | None:
    if progress is None:
        return None
    report = progress
    return lambda text: report(f"{prefix}: {text}")


def _backend_of(factory: Callable[[], Estimator]) -> str:
    if isinstance(factory, partial) and factory.func is _onnx_model:
        return f"onnx-{factory.args[1]}"
    if isinstance(factory, partial) and factory.func is _checked_model:
        return "checked"
    return "other"


def ratios(task_name: str, results: list[dict[str, Any]]) -> dict[str, Any]:
    """Each learned entry's error, latency and throughput relative to the task's reference classical
    method (the seed paper's algorithm), and its error and latency relative to the most accurate
    classical method in the same run (``best_classical``)."""
    metric, lower_better = ERROR_METRIC[task_name]
    ref = next((r for r in results if r["name"] == REFERENCE_METHOD[task_name]), None)
    if ref is None:
        return {}
    classical = [r for r in results if r["kind"] == "classical"]
    best = min(classical, key=lambda r: _error(r["metrics"], metric, lower_better))
    out: dict[str, Any] = {"reference": ref["name"], "best_classical": best["name"], "error_metric": metric}
    if not lower_better:
        out["error_metric"] = f"1 - {metric}"
    ref_error = _error(ref["metrics"], metric, lower_better)
    best_error = _error(best["metrics"], metric, lower_better)
    for r in results:
        if r["kind"] != "learned":
            continue
        err = _error(r["metrics"], metric, lower_better)
        out[f"{r['name']} [{r['backend']}]"] = {
            "error_ratio": err / ref_error if ref_error else None,
            "latency_ratio": r["latency_us_p50_b1"] / ref["latency_us_p50_b1"],
            "throughput_ratio": r["throughput_fps_b1024"] / ref["throughput_fps_b1024"],
            "error_ratio_best": err / best_error if best_error else None,
            "latency_ratio_best": r["latency_us_p50_b1"] / best["latency_us_p50_b1"],
        }
    return out


def _error(metrics: dict[str, Any], metric: str, lower_better: bool) -> float:
    value = float(metrics[metric])
    return value if lower_better else 1.0 - value


def bench_simulator(
    *, quick: bool = False, scenes: list[str] | None = None, memory_n: int | None = None
) -> dict[str, Any]:
    """Samples/s of every scene's simulator (single process) and peak memory of a generation."""

    rows = [_simulator_rate(name, quick) for name in scenes or available_scenes()]
    memory = _generation_memory("strips16", memory_n or (20_000 if quick else 100_000))
    return {"task": "simulator", "machine": machine_info(), "scenes": rows, "generation": memory}


def _simulator_rate(name: str, quick: bool, n: int = 1024) -> dict[str, Any]:
    """Samples/s of one scene's simulator at ``n`` samples a call (median of timed calls)."""
    from synth.sensors import sensor_module

    scene = load_scene(name)
    sim = sensor_module(scene.task).make_simulator(scene)
    rng = np.random.default_rng(BENCH_SEED)
    sim.simulate(64, rng)  # warm-up: builds operators and caches
    times = interleaved_times(
        {name: lambda _: sim.simulate(n, rng)}, np.zeros(1), rounds=50, warmup=0, budget_s=0.5 if quick else 2.0
    )[name]
    return {"scene": name, "task": scene.task, "samples_per_s": n / float(np.median(times)), "repeats": len(times)}


def _generation_memory(scene: str, n: int, workers: int = 2) -> dict[str, Any]:
    """Peak resident memory (MiB) of generating ``n`` samples in a fresh process, and its rate."""
    code = (
        "import resource, sys, time; from synth.scene import load_scene; from synth.dataset import generate; "
        "t = time.perf_counter(); "
        "generate(load_scene(sys.argv[1]), int(sys.argv[2]), 1, sys.argv[3], workers=int(sys.argv[4])); "
        "dt = time.perf_counter() - t; "
        # VmHWM, not ru_maxrss: Linux keeps ru_maxrss across exec, so a child of a large benchmark
        # process would report its parent's peak
        "import os; own = int([l.split()[1] for l in open('/proc/self/status') if l.startswith('VmHWM')][0]) "
        "if os.path.exists('/proc/self/status') else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss; "
        "kids = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss; "
        "print(dt, own, kids)"
    )
    with tempfile.TemporaryDirectory(prefix="tl-genmem-") as tmp:
        out = subprocess.run(
            [sys.executable, "-c", code, scene, str(n), str(Path(tmp) / "d"), str(workers)],
            check=True,
            capture_output=True,
            text=True,
        ).stdout.split()
    seconds, own_kib, child_kib = float(out[0]), int(out[1]), int(out[2])
    return {
        "scene": scene,
        "n": n,
        "workers": workers,
        "seconds": seconds,
        "samples_per_s": n / seconds,
        "peak_rss_mib_main": own_kib / 1024,
        "peak_rss_mib_worker": child_kib / 1024,
    }
