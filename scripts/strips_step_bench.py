"""The strip model's consistency step alone under onnxruntime: its separable form
(``nets.strips_consistent.ConsistencyStep``, as the shipped graph runs it) against the dense form it
replaced (the forward model's two 256 x 512 stress matrices and their transposes), each exported
as a graph of its own with the model loads as a second output, on the same maps and loads.

Rounds of ``--per-round`` calls per form in turn at batch 1, then at ``--batch`` (per-frame cost),
median and 10th percentile per call; an empty graph (two multiplications) gives onnxruntime's own
cost per call. Prints the load average before and after (figures for a report: load < 1).

    python scripts/strips_step_bench.py --rounds 300 --json results/strips_step_bench.json
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from synth.dataset import simulate_shard
from synth.scene import load_scene
from synth.sensors.strips import StripSensor
from tactile_learn.bench import record_run
from tactile_learn.export import to_onnx
from tactile_learn.nets.strip_blocks import law_gain
from tactile_learn.nets.strips_consistent import RATIO_CAP, RATIO_EPS, ConsistencyStep
from tactile_learn.nets.strips_general import StripForward
from tactile_learn.timing import interleaved_times, summary_us


class DenseStep(nn.Module):
    """The step as it shipped before its separable form: dense stress matrices (exponent 1)."""

    stress: torch.Tensor
    stress_t: torch.Tensor
    sums: torch.Tensor
    sums_t: torch.Tensor

    def __init__(self, forward: StripForward) -> None:
        super().__init__()
        self.register_buffer("stress", forward.stress.clone())
        self.register_buffer("stress_t", forward.stress.t().contiguous())
        self.register_buffer("sums", forward.sums.clone())
        self.register_buffer("sums_t", forward.sums.t().contiguous())
        self.p0 = forward.p0

    def forward(self, maps: torch.Tensor, loads: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        flat = maps.reshape(maps.shape[0], -1)
        gain = law_gain(flat @ self.stress, self.p0, 1.0)
        slope = (1.0 - gain) * (1.0 - gain)
        model = gain @ self.sums
        both = (torch.cat([loads, model], dim=0) @ self.sums_t).reshape(2, -1, self.sums_t.shape[1])
        numerator, denominator = ((both * slope) @ self.stress_t + RATIO_EPS).chunk(2, dim=0)
        return (flat * (numerator / denominator).clamp(max=RATIO_CAP)).reshape(maps.shape), model


class SeparableStep(nn.Module):
    def __init__(self, forward: StripForward) -> None:
        super().__init__()
        self.step = ConsistencyStep(forward)

    def forward(self, maps: torch.Tensor, loads: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.step.step(maps, loads)


class Empty(nn.Module):
    def forward(self, maps: torch.Tensor, loads: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return maps * 2.0, loads * 2.0


class _TwoInputs(nn.Module):
    """One input (B, N*M + N+M) for the project's exporter (one named input): split in-graph."""

    def __init__(self, step: nn.Module, n: int) -> None:
        super().__init__()
        self.step, self.n = step, n

    def forward(self, packed: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        maps, loads = packed.split([self.n * self.n, 2 * self.n], dim=1)
        out: tuple[torch.Tensor, torch.Tensor] = self.step(maps.reshape(-1, self.n, self.n), loads)
        return out


def _runner(session: Any, whole: bool = False) -> Callable[[np.ndarray], Any]:
    """``session.run`` on an item (``whole``: on the batch the item holds)."""
    if whole:
        return lambda item: session.run(None, {"packed": item[0]})
    return lambda item: session.run(None, {"packed": item})


def main(argv: list[str] | None = None) -> int:
    import onnxruntime as ort

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=300)
    parser.add_argument("--per-round", type=int, default=20)
    parser.add_argument("--batch", type=int, default=1024)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    scene = load_scene("strips16")
    forward = StripForward(scene)
    n = scene.sensor.geometry.n_rows
    arrays = simulate_shard(scene, 515151, 0, max(args.batch, 512))
    loads = StripSensor(scene.sensor).invert_readings(arrays["readings"])
    packed = np.concatenate([arrays["pressure"].reshape(len(loads), -1), loads], axis=1).astype(np.float32)
    forms: dict[str, nn.Module] = {
        "empty graph": Empty(),
        "dense (256 x 512 matrices)": DenseStep(forward),
        "separable (ConsistencyStep)": SeparableStep(forward),
    }
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    # the shipped strip model's card setting (graph_optimization "extended")
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_EXTENDED
    sessions: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, module in forms.items():
            path = Path(tmp) / f"{len(sessions)}.onnx"
            to_onnx(_TwoInputs(module, n).eval(), torch.from_numpy(packed[:2]), path, "packed", ["maps", "model"], {})
            sessions[name] = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    dense, separable = (sessions[k].run(None, {"packed": packed}) for k in list(forms)[1:])
    calls = {name: _runner(session) for name, session in sessions.items()}
    load_before = os.getloadavg()
    single = interleaved_times(calls, packed, rounds=args.rounds, per_round=args.per_round, warmup=50)
    bulk_rounds = max(5, args.rounds // 20)
    # one item: the whole batch (interleaved_times hands out items as batches of one)
    bulk = interleaved_times(
        {name: _runner(session, whole=True) for name, session in sessions.items()},
        packed[None, : args.batch],
        rounds=bulk_rounds,
        warmup=2,
    )
    result: dict[str, Any] = {
        "batch1_median_us": {k: summary_us(v)["median_us"] for k, v in single.items()},
        "batch1_p10_us": {k: float(np.percentile(v, 10) * 1e6) for k, v in single.items()},
        f"batch{args.batch}_per_frame_median_us": {k: summary_us(v)["median_us"] / args.batch for k, v in bulk.items()},
        "max_abs_diff_maps_kpa": float(np.abs(dense[0] - separable[0]).max()),
        "max_abs_diff_model_loads": float(np.abs(dense[1] - separable[1]).max()),
    }
    for name in forms:
        print(
            f"{name:30s} batch 1 median {result['batch1_median_us'][name]:7.2f} us (p10 "
            f"{result['batch1_p10_us'][name]:7.2f})   batch {args.batch} "
            f"{result[f'batch{args.batch}_per_frame_median_us'][name]:7.3f} us/frame"
        )
    print(
        f"dense vs separable: maps max |diff| {result['max_abs_diff_maps_kpa']:.3g} kPa, "
        f"model loads {result['max_abs_diff_model_loads']:.3g}"
    )
    record_run(result, "strips_step_bench.py", argv, load_before[0], args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
