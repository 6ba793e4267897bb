"""Frame speed, in one run: per-frame overhead of every estimator, gated streams, large skins.

**overhead** - batch-1 latency against the per-frame cost at batch 1024.

For each task (strips, fsr, thermal, capacitive) and each of its methods (classical, and every
shipped ONNX model of the task's sensor under onnxruntime with 1 thread), on held-out frames of the
task's default scene (``--frames``, 64), in interleaved rounds (every method sees the same machine
load): ``--per-round`` passes over all the frames one at a time (batch 1), then one call at batch 1024
on the same frames repeated (each frame 16 times). Both sides therefore see the same mix of frames:
a method whose cost depends on the frame (an FSR frame without contact, a thermal curve without a
detected touch returns early) is compared at equal mix, not by a median that lands on the cheap
frames. Reported per method:

- ``b1_us``: time of one ``predict`` call on one frame (us): each frame's median over rounds, then
  the mean over the frames;
- ``b1_median_us``: the median single call (a typical frame's latency), for reference;
- ``b1024_us_per_frame``: the batch-1024 call's time over 1024 (us), median over rounds;
- ``overhead_ratio``: ``b1_us / b1024_us_per_frame`` (the target is <= 3 where physically
  possible; an onnxruntime call alone costs ~12 us, which bounds a small network's ratio);
- the same for ``stream`` (:class:`tactile_learn.frame_stream.FrameStream`: checks and set-up once per
  session, the documented fast path for single frames) where it applies.

**gating** - a stream of frames, ``--idle-share`` (80 %) of them the sensor at rest, the rest
touches of the model's training scene, through :class:`~tactile_learn.frame_stream.FrameStream` frame by
frame and in batches of 1024, with and without the idle gate: frames/s (median of ``--repeats``
interleaved passes), the share skipped, and the largest difference between gated and ungated
results on the active frames.

**skins** - two Hertz spheres (strips16's stimuli) on the 16 x 16 array (the shipped strips16
model) and on a 128 x 128 skin of the same strips (:class:`~tactile_learn.skins.SkinReconstructor`:
the same model on windows): batch-1 latency (median, interleaved), Pearson r over the whole map and
over the crossings of the rows and columns that carry pressure in the truth or the estimate.

    python scripts/latency_overhead.py --json results/latency_overhead.json
"""

from __future__ import annotations

import os

# every method on one thread, as the ONNX models run: a threaded BLAS matvec (calibrated) spikes to
# milliseconds when the other core is busy; set before numpy loads its BLAS
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from collections.abc import Callable  # noqa: E402
from functools import partial  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from synth.scene import Scene, load_scene  # noqa: E402
from tactile_learn.bench import _bench_data, _same_sensor, machine_info, record_run  # noqa: E402
from tactile_learn.methods import shipped_models  # noqa: E402
from tactile_learn.runtime import OnnxEstimator, read_card  # noqa: E402
from tactile_learn.tasks import get_task  # noqa: E402
from tactile_learn.timing import interleaved_times, summary_us, timed  # noqa: E402

TASKS = ("strips", "fsr", "thermal", "capacitive")


def methods_of(task_name: str, scene: Scene, before: Path | None = None) -> dict[str, Any]:
    """Every classical method and every shipped model of ``scene``'s sensor (1 thread); with
    ``before``, also every model of the task in that folder, run as the runtime ran it before the
    load-time fusions (``fuse=False``; e.g. main's models beside re-exported ones, in one run)."""
    task = get_task(task_name)
    found: dict[str, Any] = {name: factory(scene) for name, factory in task.classical_methods().items()}
    models = [(f"{name}.onnx", path, True) for name, path in sorted(shipped_models(task_name).items())]
    if before is not None:
        models += [(f"{p.name} (before)", p, False) for p in sorted(before.glob("*.onnx"))]
    for label, path, fuse in models:
        card = read_card(path)
        if card["task"] != task_name:
            continue
        if card["scene_digest"] == scene.digest:
            found[label] = OnnxEstimator(path, threads=1, fuse=fuse).prepare()
        elif _same_sensor(task_name, card["scene"], scene):
            found[label] = OnnxEstimator(path, threads=1, scene=scene, fuse=fuse).prepare()
    return found


def _batch_of(call: Callable[[np.ndarray], Any], big: np.ndarray) -> Callable[[np.ndarray], Any]:
    """``call`` on the batch ``big`` whatever frame the timer hands it."""
    return lambda _frame: call(big)


def measure(
    calls: dict[str, Callable[[np.ndarray], Any]], frames: np.ndarray, rounds: int, passes: int
) -> dict[str, dict[str, float]]:
    """Batch 1 against batch 1024 on the same mix of frames (see the module's docstring)."""
    singles = np.ascontiguousarray(frames, dtype=np.float32)
    n = len(singles)
    big = np.ascontiguousarray(np.resize(singles, (1024, *singles.shape[1:])))
    slow: set[str] = set()
    for name, call in calls.items():  # warm-up: sessions, caches, lazily fitted state
        for i in range(20):
            call(singles[i % n : i % n + 1])
        if timed(partial(call, big))[1] > 0.5:  # seconds per batch: 3 rounds of one pass each
            slow.add(name)
    timed_calls: dict[str, Callable[[np.ndarray], Any]] = {}
    for name, call in calls.items():  # each round: the frames one by one, then the batch
        timed_calls[f"{name}|b1"], timed_calls[f"{name}|b1024"] = call, _batch_of(call, big)
    own_rounds = {k: 3 if k.split("|")[0] in slow else rounds for k in timed_calls}
    own_passes = {k: 1 if k.split("|")[0] in slow else passes for k in timed_calls}
    times = interleaved_times(
        timed_calls,
        singles,
        rounds=own_rounds,
        # item (r * per_round + k) % n: a multiple of n per round is whole passes, every frame alike
        per_round={k: 1 if k.endswith("b1024") else own_passes[k] * n for k in timed_calls},
        warmup=0,
    )
    out = {}
    for name in calls:
        single = times[f"{name}|b1"].reshape(own_rounds[f"{name}|b1"], -1)
        # each frame's median over rounds (robust to a pre-empted call), then the mean over the mix
        b1 = float(np.median(single, axis=0).mean()) * 1e6
        per_frame = summary_us(times[f"{name}|b1024"])["median_us"] / len(big)
        out[name] = {
            "b1_us": b1,
            "b1_median_us": summary_us(single.ravel())["median_us"],
            "b1024_us_per_frame": per_frame,
            "overhead_ratio": b1 / per_frame,
            "frames": n,
        }
    return out


def idle_mixed(scene: Scene, n: int, idle_share: float, seed: int = 31) -> tuple[np.ndarray, np.ndarray]:
    """Inputs of ``n`` frames of ``scene``'s sensor, ``idle_share`` of them at rest, shuffled; and
    which frames were touched."""
    from synth.dataset import simulate_shard
    from tactile_learn.idle import idle_scene

    task = get_task(scene.task)
    n_idle = round(idle_share * n)
    rest = idle_scene(scene)
    # a sample may hold several frames (a capacitive press: 8): the first ones are kept
    idle = task.example_inputs(simulate_shard(rest, seed, 0, n_idle), rest)[:n_idle]
    busy = task.example_inputs(simulate_shard(scene, seed, 1, n - n_idle), scene)[: n - n_idle]
    order = np.random.default_rng(seed).permutation(n)
    frames = np.ascontiguousarray(np.concatenate([idle, busy])[order], dtype=np.float32)
    return frames, order >= n_idle


def _frame_by_frame(
    stream: Any, singles: list[np.ndarray], outputs: dict[str, np.ndarray], way: str
) -> Callable[[np.ndarray], Any]:
    """A pass of ``stream`` over ``singles`` one frame at a time; its results land in ``outputs[way]``."""

    def run(_frame: np.ndarray) -> None:
        outputs[way] = np.concatenate([stream.predict(f) for f in singles])

    return run


def bench_gating(model_name: str, n: int, idle_share: float, repeats: int) -> dict[str, Any]:
    from tactile_learn.frame_stream import FrameStream

    est = OnnxEstimator(shipped_models_any(model_name), threads=1).prepare()
    frames, touched = idle_mixed(est.card_scene_, n, idle_share)
    ways = {"ungated": FrameStream(est), "gated": FrameStream(est, gate=True)}
    singles = [frames[i : i + 1] for i in range(n)]
    outputs: dict[str, np.ndarray] = {}
    passes: dict[str, Callable[[np.ndarray], Any]] = {}
    for way, stream in ways.items():  # each a whole pass over the frames: one by one, then in batches
        passes[f"{way} b1"] = _frame_by_frame(stream, singles, outputs, way)
        passes[f"{way} b1024"] = _batch_of(partial(stream.run, batch=1024), frames)
    seconds = interleaved_times(passes, np.zeros(1), rounds=repeats, warmup=0)
    fps = {k: n / float(np.median(v)) for k, v in seconds.items()}
    gate = ways["gated"].gate
    assert gate is not None
    active = gate.active(frames)
    diff = np.abs(outputs["gated"][active] - outputs["ungated"][active])
    return {
        "model": model_name,
        "frames": n,
        "idle_share": idle_share,
        "skipped_share": float(1.0 - active.mean()),
        "touched_frames_gated_idle": int((touched & ~active).sum()),
        "frames_per_s": fps,
        "speedup_b1": fps["gated b1"] / fps["ungated b1"],
        "speedup_b1024": fps["gated b1024"] / fps["ungated b1024"],
        "max_abs_diff_active": float(diff.max()) if diff.size else 0.0,
        "ungated_max_abs_output_on_skipped": float(np.abs(outputs["ungated"][~active]).max()),
    }


def shipped_models_any(name: str) -> Any:
    for task_name in TASKS:
        found = shipped_models(task_name)
        if name in found:
            return found[name]
    raise SystemExit(f"no shipped model {name!r}")


def cross_r(pred: np.ndarray, truth: np.ndarray) -> float:
    """Mean Pearson r over the crossings of the rows and columns that carry pressure in the truth or
    the estimate (the whole-map r of a large skin counts every idle crossing as a correct zero)."""
    from tactile_learn.metrics import pearson_per_frame

    values = []
    for p, t in zip(pred, truth, strict=True):
        rows = np.flatnonzero((p > 0).any(axis=1) | (t > 0).any(axis=1))
        cols = np.flatnonzero((p > 0).any(axis=0) | (t > 0).any(axis=0))
        r = pearson_per_frame(p[np.ix_(rows, cols)][None], t[np.ix_(rows, cols)][None])[0]
        if np.isfinite(r):
            values.append(r)
    return float(np.mean(values))


def bench_skins(n: int, rounds: int, per_round: int) -> dict[str, Any]:
    from synth.dataset import simulate_shard
    from synth.scene import parse_scene
    from tactile_learn.skins import SkinReconstructor
    from tactile_learn.tasks.strips import strip_map_metrics

    small = load_scene("strips16")
    data = small.to_dict()
    data["name"] = "strips128_two_spheres"
    data["strips"]["geometry"].update(n_rows=128, n_cols=128)
    data["strips"]["readout"]["amplifier_gain"] = load_scene("strips128").sensor.readout.amplifier_gain
    large = parse_scene(data)
    seed = 909_090
    frames_small, frames_large = simulate_shard(small, seed, 0, n), simulate_shard(large, seed, 0, n)
    model = OnnxEstimator(shipped_models("strips")["strips16"], threads=1).prepare()
    skin = SkinReconstructor(large, model).fit()
    pred_small, pred_large = model.predict(frames_small["readings"]), skin.predict(frames_large["readings"])
    quality = {}
    for label, pred, truth in (
        ("16x16 strips16", pred_small, frames_small["pressure"]),
        ("128x128 skin", pred_large, frames_large["pressure"]),
    ):
        metrics = strip_map_metrics(pred, truth, small.sensor.geometry.pitch_mm)
        quality[label] = {"pearson_r_mean": metrics["pearson_r_mean"], "cross_r_mean": cross_r(pred, truth)}
    times = interleaved_times(
        {"16x16 strips16": model.predict, "128x128 skin": skin.predict},
        {
            "16x16 strips16": np.ascontiguousarray(frames_small["readings"], dtype=np.float32),
            "128x128 skin": np.ascontiguousarray(frames_large["readings"], dtype=np.float32),
        },
        rounds=rounds,
        per_round=per_round,
        warmup=0,
    )
    b1 = {k: float(np.median(v) * 1e6) for k, v in times.items()}
    return {
        "frames": n,
        "quality": quality,
        "b1_us": b1,
        "latency_ratio_128_over_16": b1["128x128 skin"] / b1["16x16 strips16"],
        "r_difference_128_minus_16": quality["128x128 skin"]["pearson_r_mean"]
        - quality["16x16 strips16"]["pearson_r_mean"],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    parser.add_argument("--frames", type=int, default=64, help="held-out frames (touches for thermal) per task")
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--per-round", type=int, default=1, help="passes over the frames per round (overhead)")
    parser.add_argument("--no-stream", action="store_true", help="time predict only, not the streaming fast path")
    parser.add_argument("--sections", nargs="+", default=["overhead", "gating", "skins"])
    parser.add_argument("--gating-models", nargs="+", default=["strips16", "fsr", "capacitive8"])
    parser.add_argument("--idle-share", type=float, default=0.8)
    parser.add_argument("--stream-frames", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--skin-frames", type=int, default=300)
    parser.add_argument("--before", type=Path, default=None, help="models (cards beside) to time unfused too")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    load_before = os.getloadavg()[0]
    result: dict[str, Any] = {"machine": machine_info(), "tasks": {}}
    for task_name in args.tasks if "overhead" in args.sections else []:
        task = get_task(task_name)
        data = _bench_data(task_name, None, args.frames, None)
        frames = np.asarray(task.latency_inputs(data), dtype=np.float32)
        calls: dict[str, Callable[[np.ndarray], Any]] = {}
        for name, est in methods_of(task_name, load_scene(task.default_scene), args.before).items():
            calls[name] = est.predict
            if not args.no_stream:
                from tactile_learn.frame_stream import FrameStream

                calls[f"{name} [stream]"] = FrameStream(est).predict
        result["tasks"][task_name] = measure(calls, frames, args.rounds, args.per_round)
        for name, row in result["tasks"][task_name].items():
            print(
                f"{task_name:10s} {name:34s} b1 {row['b1_us']:8.1f} us  b1024 {row['b1024_us_per_frame']:8.2f} us/frame"
                f"  ratio {row['overhead_ratio']:6.1f}",
                flush=True,
            )
    if "gating" in args.sections:
        result["gating"] = [
            bench_gating(m, args.stream_frames, args.idle_share, args.repeats) for m in args.gating_models
        ]
        for row in result["gating"]:
            print(
                f"gating {row['model']:12s} skipped {100 * row['skipped_share']:.1f} %  speedup b1 "
                f"{row['speedup_b1']:.2f}x  b1024 {row['speedup_b1024']:.2f}x  {row['frames_per_s']}",
                flush=True,
            )
    if "skins" in args.sections:
        result["skins"] = bench_skins(args.skin_frames, args.rounds, per_round=20)
        print(f"skins {json.dumps(result['skins'])}", flush=True)
    record_run(result, "latency_overhead.py", argv, load_before, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
