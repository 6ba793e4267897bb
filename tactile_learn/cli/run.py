"""tactile-learn run: a stream of frames from a file through one method, idle frames skipped."""

from __future__ import annotations

import argparse
import time

from synth.dataset import load_arrays
from synth.errors import DataError
from synth.io import atomic_save_npz, atomic_write_json
from synth.scene import load_scene
from tactile_learn.cli.common import on_off, positive_int
from tactile_learn.frame_stream import FrameStream
from tactile_learn.idle import IDLE_KEYS
from tactile_learn.methods import model_scene, resolve_method
from tactile_learn.tasks import TASK_NAMES, get_task

HELP = "run a method on a file of frames (the streaming fast path), skipping idle frames"
EXAMPLES = """\
  tactile-learn run --task strips --method strips16 --frames frames.npz --out maps.npz
  tactile-learn run --task fsr --method fsr --frames presses.npz --out estimates.npz --json stats.json
  tactile-learn run --task strips --method strips16 --frames frames.npz --out maps.npz --gate off
The .npz holds the task's input array ('readings' for strips and fsr, 'cell_load' for capacitive),
batch first. The output holds the prediction under the task's output name ('pressure', 'estimate',
'image') and 'active' (B,): False where the frame was within the sensor's noise floor at rest (the
model card's idle floor; a classical method's is measured on the scene first) and got the empty
result (no contact) without running the method. A model's card must carry the floor
(scripts/idle_floor.py adds it). The thermal task has no gate."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", required=True, choices=TASK_NAMES)
    parser.add_argument(
        "--method",
        required=True,
        help="shipped model name, MODEL.onnx, a known-objects bundle (DIR), or a classical method",
    )
    parser.add_argument("--frames", required=True, help=".npz with the task's input array")
    parser.add_argument("--out", required=True, help="output .npz")
    parser.add_argument("--scene", default=None, help="scene of the frames (default: the model's, else the task's)")
    parser.add_argument(
        "--gate", type=on_off, default=None, help="on|off: skip idle frames (default on, except for thermal: no gate)"
    )
    parser.add_argument("--batch", type=positive_int, default=1024, help="frames per call (default 1024)")
    parser.add_argument("--threads", type=positive_int, default=1, help="onnxruntime threads (default 1)")
    parser.add_argument("--json", default=None, help="also write the run's statistics to this JSON file")


def run(args: argparse.Namespace) -> int:
    task = get_task(args.task)
    scene = load_scene(args.scene) if args.scene else model_scene(args.task, args.method)
    scene = scene or load_scene(task.default_scene)
    estimator = resolve_method(args.task, args.method, scene, threads=args.threads)
    arrays = load_arrays(args.frames)
    if task.input_key not in arrays:
        raise DataError(f"{args.frames}: needs an array {task.input_key!r} (the task's input), has {sorted(arrays)}")
    gate = args.gate if args.gate is not None else args.task in IDLE_KEYS
    stream = FrameStream(estimator, gate=gate)
    frames = stream.check(arrays[task.input_key])
    if not len(frames):
        raise DataError(f"{args.frames}: {task.input_key!r} holds no frames (shape {frames.shape})")
    start = time.perf_counter()
    prediction = stream.run(frames, batch=args.batch)
    seconds = time.perf_counter() - start
    out = {task.output_key: prediction}
    if stream.gate is not None:
        out["active"] = stream.gate.active(frames)
    atomic_save_npz(args.out, out)
    stats = {
        "frames": stream.frames,
        "skipped": stream.skipped,
        "skipped_share": stream.skipped_share,
        "seconds": seconds,
        "frames_per_s": stream.frames / seconds if seconds > 0 else float("inf"),
        "gate": bool(gate),
    }
    print(
        f"wrote {args.out}: {task.output_key} {prediction.shape}; {stream.frames} frames, "
        f"{stream.skipped} idle ({100 * stream.skipped_share:.1f} %) skipped, {stats['frames_per_s']:.0f} frames/s"
    )
    if args.json:
        atomic_write_json(args.json, stats)
    return 0
