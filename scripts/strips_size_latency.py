"""How big a general strip network fits a batch-1 budget: latency of untrained networks of any size.

Latency does not depend on the weights, so each size is a freshly initialised
:class:`~tactile_learn.nets.strips_general.GeneralStripNet` (seeded), exported exactly as ``export``
exports a trained one (the task's deployed graph, the shipped strips16 card's normalisation and
ONNX metadata; ``--consistent``: with the ISRA step of ``wide_consistent``) and run by the runtime
as a shipped model is (:class:`~tactile_learn.runtime.OnnxEstimator`: the graph cut to its first
output and fused at load; a copy of the strips16 card with the new checksum beside it). All sizes
and the shipped models named by ``--shipped`` are timed in interleaved rounds: ``predict`` of one
frame (median us) and the batch-1024 call per frame (median us), on held-out frames of strips16.

A size is ``ENC,HIDDEN,CONTEXT,BLOCKS[,c]`` (strip encoder channels, crossing channels, context
width, mixing blocks; ``c``: with the consistency step), e.g. ``24,24,192,2,c`` is ``wide_consistent``
(the shipped strips16) and ``16,8,96,1`` is ``tiny`` (strips16_small).

    python scripts/strips_size_latency.py --sizes 24,24,192,2,c 24,32,192,3,c 24,16,192,2 \\
        --json results/strips_size_latency.json
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import copy  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
import torch  # noqa: E402

from synth.dataset import simulate_shard  # noqa: E402
from synth.errors import ConfigError  # noqa: E402
from synth.io import atomic_write_json, sha256_file  # noqa: E402
from tactile_learn.bench import BENCH_SEED, record_run  # noqa: E402
from tactile_learn.export import to_onnx  # noqa: E402
from tactile_learn.methods import shipped_models  # noqa: E402
from tactile_learn.nets import strips_general  # noqa: E402
from tactile_learn.runtime import OnnxEstimator, card_path, read_card  # noqa: E402
from tactile_learn.tasks import get_task  # noqa: E402
from tactile_learn.timing import interleaved_times, summary_us  # noqa: E402


def parse_size(text: str) -> tuple[int, int, int, int, bool]:
    parts = text.split(",")
    consistent = parts[-1] == "c"
    numbers = parts[:-1] if consistent else parts
    if len(numbers) != 4 or not all(p.isdigit() and int(p) > 0 for p in numbers):
        raise ConfigError(f"size {text!r}: expected ENC,HIDDEN,CONTEXT,BLOCKS[,c] (positive integers)")
    enc, hidden, context, blocks = (int(p) for p in numbers)
    return enc, hidden, context, blocks, consistent


def untrained_model(size: str, folder: Path, seed: int) -> Path:
    """The network of ``size`` (``parse_size``), initialised from ``seed``, exported beside a copy
    of the shipped strips16 card (its scene and normalisation; the checksum and size of this file)."""
    enc, hidden, context, blocks, consistent = parse_size(size)
    reference = shipped_models("strips")["strips16"]
    card = read_card(reference)
    name = f"size_{size.replace(',', '_')}"
    # a size name of its own, registered for this process only (the registries are module globals)
    strips_general.SIZES[name] = (enc, hidden, context, blocks, False)
    if consistent:
        strips_general.CONSISTENT_SIZES = strips_general.CONSISTENT_SIZES | {name}
    from tactile_learn.torch_estimator import TorchEstimator

    scene = TorchEstimator.from_checkpoint(reference.with_suffix(".pt"), threads=1).scene
    torch.manual_seed(seed)
    net = strips_general.GeneralStripNet(scene, card["normalisation"], name).eval()
    task = get_task("strips")
    graph, outputs = task.export_module(net, scene)
    path = folder / f"{name}.onnx"
    import onnx

    metadata = json.loads({p.key: p.value for p in onnx.load(str(reference)).metadata_props}["tactile_learn"])
    example = torch.from_numpy(simulate_shard(scene, seed, 0, 2)["readings"])
    to_onnx(graph.eval(), example, path, task.input_key, outputs, {**metadata, "size": name})
    own = copy.deepcopy(card)
    own.pop("route", None)  # one untrained network: the shipped card's routed member is not this size's
    own.update(name=name, model_file=path.name, model_sha256=sha256_file(path), model_bytes=path.stat().st_size)
    own["network"] = {"size": size, "parameters": int(sum(p.numel() for p in net.parameters()))}
    atomic_write_json(card_path(path), own)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", nargs="+", required=True, type=str)
    parser.add_argument("--shipped", nargs="*", default=["strips16", "strips16_small"])
    parser.add_argument("--rounds", type=int, default=30)
    parser.add_argument("--per-round", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    for size in args.sizes:
        parse_size(size)  # every size checked before anything is built
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        models: dict[str, Any] = {}
        parameters: dict[str, int] = {}
        for name in args.shipped:
            path = shipped_models("strips")[name]
            models[f"{name}.onnx"] = OnnxEstimator(path, threads=1).prepare()
            parameters[f"{name}.onnx"] = int(read_card(path)["network"]["parameters"])
        for size in args.sizes:
            path = untrained_model(size, Path(tmp), args.seed)
            models[size] = OnnxEstimator(path, threads=1).prepare()
            parameters[size] = int(read_card(path)["network"]["parameters"])
        scene = models[next(iter(models))].card_scene_
        frames = np.ascontiguousarray(simulate_shard(scene, BENCH_SEED, 0, 64)["readings"], dtype=np.float32)
        big = np.ascontiguousarray(np.resize(frames, (1024, frames.shape[1])))
        calls: dict[str, Any] = {}
        for label, model in models.items():
            calls[f"{label}|b1"] = model.predict
            calls[f"{label}|b1024"] = lambda _frame, predict=model.predict: predict(big)
        per_round = {k: 1 if k.endswith("b1024") else args.per_round for k in calls}
        times = interleaved_times(calls, frames, rounds=args.rounds, per_round=per_round, warmup=20)
    result: dict[str, Any] = {"sizes": {}}
    for label in models:
        b1 = summary_us(times[f"{label}|b1"])["median_us"]
        b1024 = summary_us(times[f"{label}|b1024"])["median_us"] / len(big)
        result["sizes"][label] = {
            "parameters": parameters[label],
            "b1_us": b1,
            "b1024_us_per_frame": b1024,
            "ratio": b1 / b1024,
        }
        row = f"{label:22s} {parameters[label]:7d} params  b1 {b1:7.1f} us  b1024 {b1024:6.2f} us/frame"
        print(f"{row}  ratio {b1 / b1024:4.1f}", flush=True)
    record_run(result, "strips_size_latency.py", argv, load_before, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
