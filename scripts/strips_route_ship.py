"""Build a routed strip model (:mod:`tactile_learn.prior_route`) from a library model, a generic model and a
router trained by ``scripts/strips_prior_router.py``: ``OUT/NAME.onnx`` (the library model's graph, its
card given a ``route`` block), ``OUT/NAME_generic.onnx`` with its card (and ``.pt`` weights where the run
has them), and ``OUT/NAME_route.npz`` (the router's weights and the features' normalisation).

Nothing is retrained or re-exported: the two graphs are copied byte for byte, and the router's weights
are read from its ONNX initializers, so the runtime's routing is the script's (``strips_prior_router``'s
``PriorRouted``) to float32 rounding of the router's logit; ``--check`` compares the two on frames
and reports every frame routed differently; ``--latency`` times the routed model's batch-1 ``predict``
against the library model's, interleaved on the same frames (onnxruntime, one thread), medians::

    python scripts/strips_route_ship.py --library models/strips16.onnx --generic runs/shapes/model.onnx \\
        --generic-weights runs/shapes/run/model.pt --router runs/prior-router --out models --name strips16 \\
        --check data/strips16-test --latency data/shapes-train
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np

OFFSET, SHARE_SCALE = 0.3, 16.0  # strips_experts.features: readings above the readout's offset, shares x 16


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def router_arrays(router: Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The router's weights (``PriorRoute`` names) from ``router/router.onnx`` and its card."""
    import onnx
    from onnx import numpy_helper

    card = json.loads((router / "router.json").read_text())
    graph = onnx.load(str(router / "router.onnx")).graph
    gemms = [n for n in graph.node if n.op_type == "Gemm"]
    weights = {t.name: numpy_helper.to_array(t) for t in graph.initializer}
    if len(gemms) != 3 or any(
        not any(a.name == "transB" and a.i == 1 for a in n.attribute) for n in gemms
    ):  # (the exported MLP: three Gemm layers, weights transposed)
        raise SystemExit(f"{router}/router.onnx is not the three-layer MLP this script reads")
    arrays = {"mean": np.asarray(card["mean"]), "std": np.asarray(card["std"])}
    for i, node in enumerate(gemms):
        arrays[f"w{i}"], arrays[f"b{i}"] = weights[node.input[1]], weights[node.input[2]]
    return arrays, card


def build(library: Path, generic: Path, generic_weights: Path | None, router: Path, out: Path, name: str) -> Path:
    from tactile_learn.prior_route import PriorRoute

    arrays, router_card = router_arrays(router)  # every input read before anything is written
    generic_card = json.loads(generic.with_suffix(".json").read_text())
    card = json.loads(library.with_suffix(".json").read_text())
    out.mkdir(parents=True, exist_ok=True)
    route_file = out / f"{name}_route.npz"
    PriorRoute.save(route_file, arrays)
    generic_name = f"{name}_generic"
    shutil.copyfile(generic, out / f"{generic_name}.onnx")
    generic_card |= {"name": generic_name, "model_file": f"{generic_name}.onnx", "routed_by": f"{name}.json"}
    (out / f"{generic_name}.json").write_text(json.dumps(generic_card, indent=2) + "\n")
    if generic_weights is not None:
        shutil.copyfile(generic_weights, out / f"{generic_name}.pt")
    if library.resolve() != (out / f"{name}.onnx").resolve():
        shutil.copyfile(library, out / f"{name}.onnx")
    card["route"] = {
        "generic_model": f"{generic_name}.onnx",
        "router": route_file.name,
        "router_sha256": _sha256(route_file),
        "offset": OFFSET,
        "share_scale": SHARE_SCALE,
        "threshold": float(router_card["threshold"]),
        "router_held_out_accuracy": router_card.get("held_out_accuracy"),
        "trained_by": "python scripts/strips_prior_router.py train --out runs/prior-router",
        "built_by": "python scripts/strips_route_ship.py (docs/strips.md, 'Round 7')",
    }
    path = out / f"{name}.onnx"
    card_file = path.with_suffix(".json")
    tmp = card_file.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(card, indent=2) + "\n")
    tmp.replace(card_file)  # the card last, whole: a routed card never names files not yet written
    return path


def check(path: Path, router: Path, data: Path, members: dict[str, str] | None = None) -> dict[str, Any]:
    """The routed model against the script's routing of the same ``members`` (library and generic model
    files; default: those the router's card names) on ``data``'s frames: frames routed differently, the
    largest difference of the maps, and single frames against the batch."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from strips_experts import read_frames
    from strips_prior_router import PriorRouted

    from tactile_learn.runtime import OnnxEstimator

    readings, _ = read_frames(data)
    model = OnnxEstimator(path, threads=1).prepare()
    script = PriorRouted(router, members)
    ours, theirs = model.route_[0].generic(readings), script.generic(readings)
    batch = model.predict(readings)
    single = np.concatenate([model.predict(readings[i : i + 1]) for i in range(min(len(readings), 500))])
    return {
        "frames": len(readings),
        "generic_share": float(ours.mean()),
        "routed_differently": int((ours != theirs).sum()),
        "max_abs_diff_vs_script": float(np.abs(batch - script.predict(readings)).max()),
        "max_abs_diff_single_vs_batch": float(np.abs(single - batch[: len(single)]).max()),
    }


def latency(path: Path, library: Path, data: Path, frames: int = 64, rounds: int = 30) -> dict[str, Any]:
    """Batch-1 ``predict`` of the routed model and of the library model alone, in turns on the same
    ``frames`` frames of ``data`` (each round one pass over them): the median call (us), and the share
    of those frames the router sends on."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from strips_experts import read_frames

    from tactile_learn.runtime import OnnxEstimator
    from tactile_learn.timing import interleaved_times, summary_us

    readings = read_frames(data)[0][:frames]
    routed = OnnxEstimator(path, threads=1).prepare()
    calls = {"library": OnnxEstimator(library, threads=1).prepare().predict, "routed": routed.predict}
    times = interleaved_times(calls, readings, rounds=rounds, per_round=frames)
    return {
        "frames": len(readings),
        "generic_share": float(routed.route_[0].generic(readings).mean()),
        **{f"{k}_b1_median_us": summary_us(v)["median_us"] for k, v in times.items()},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--library", type=Path, default=Path("models/strips16.onnx"))
    parser.add_argument("--generic", type=Path, default=Path("runs/shapes/model.onnx"))
    parser.add_argument("--generic-weights", type=Path, help="the generic run's torch weights, shipped beside it")
    parser.add_argument("--router", type=Path, default=Path("runs/prior-router"))
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--name", default="strips16")
    parser.add_argument("--check", type=Path, help="a dataset to compare the routing with the script's on")
    parser.add_argument("--latency", type=Path, help="a dataset whose frames time batch 1 against the library model")
    args = parser.parse_args(argv)
    path = build(args.library, args.generic, args.generic_weights, args.router, args.out, args.name)
    print(f"wrote {path} (routed), {args.out / (args.name + '_generic.onnx')}, {args.out / (args.name + '_route.npz')}")
    if args.check is not None:
        members = {"library": str(args.library), "generic": str(args.generic)}
        print(json.dumps(check(path, args.router, args.check, members), indent=1))
    if args.latency is not None:
        print(json.dumps(latency(path, args.library, args.latency), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
