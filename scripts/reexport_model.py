"""Re-export a shipped model from its weights (``NAME.pt``) with its task's current export graph.

When a task's export graph changes but not the network (the FSR network's lean graph,
:mod:`tactile_learn.nets.fsr_deploy`), the shipped weights need no new training: this script
writes ``NAME.onnx`` again from ``NAME.pt`` and keeps the card's training record. It

1. builds the export graph (``task.export_module``) of the saved network and writes it with the
   metadata the shipped graph carries (scene digest, normalisation, ...);
2. checks parity against the torch export module (the export's check, :data:`PARITY_TOL` of each
   output's range) and against the shipped graph on the same frames; nothing is written if either
   fails;
3. replaces the ONNX file (atomic write), updates the card's checksum, size, parity and export
   time, and re-measures every held-out dataset entry (regenerated under ``data/`` from the
   scene, seed and size the card records), printing recorded against new values.

    python scripts/reexport_model.py models/fsr.onnx
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from synth.dataset import generate
from synth.errors import ModelError
from synth.io import atomic_open, atomic_write_json, sha256_file
from synth.scene import load_scene
from tactile_learn.cards import DEFAULT_SHARD_SIZE, add_metrics, heldout_sets
from tactile_learn.export import PARITY_TOL, _probe_inputs, parity_check, to_onnx
from tactile_learn.provenance import command_line
from tactile_learn.runtime import METADATA_KEY, card_path, read_card
from tactile_learn.tasks import get_task
from tactile_learn.torch_estimator import TorchEstimator


def shipped_metadata(model: Path) -> dict[str, Any]:
    import onnx

    props = {p.key: p.value for p in onnx.load(str(model), load_external_data=False).metadata_props}
    if METADATA_KEY not in props:
        raise ModelError(f"{model}: the ONNX graph carries no tactile-learn metadata")
    metadata: dict[str, Any] = json.loads(props[METADATA_KEY])
    return metadata


def output_difference(old: Path, new: Path, inputs: np.ndarray) -> float:
    """Largest difference of the two graphs' outputs, each over the old output's range (the worst
    over the outputs of a graph with several: a strip map and its check outputs)."""
    import onnxruntime as ort

    results = []
    for path in (old, new):
        session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
        results.append(session.run(None, {session.get_inputs()[0].name: inputs}))
    worst = 0.0
    for before, after in zip(*results, strict=True):
        span = float(before.max() - before.min()) or 1.0
        worst = max(worst, float(np.abs(after - before).max()) / span)
    return worst


def reexport(model: Path) -> dict[str, Any]:
    card = read_card(model)
    task = get_task(card["task"])
    trained = TorchEstimator.from_checkpoint(model.with_suffix(".pt"), threads=1)
    if trained.scene.digest != card["scene_digest"]:
        raise ModelError(f"{model}: the weights beside it were trained on another scene than its card's")
    graph, output_names = task.export_module(trained.net, trained.scene)
    graph.eval()
    inputs = _probe_inputs(task.name, trained.scene, 512)
    import torch

    with tempfile.TemporaryDirectory(dir=model.parent) as tmp:
        new = Path(tmp) / model.name
        to_onnx(graph, torch.from_numpy(inputs[:2]), new, task.input_key, output_names, shipped_metadata(model))
        # against the export module, as `export` checks it (a task's export module is itself checked
        # against the trained network, e.g. the strip network's deployed form)
        parity = parity_check(graph, new, inputs)
        worst = max(parity["rel_err_b1"], parity["rel_err_b7"])
        moved = output_difference(model, new, inputs)
        if worst > PARITY_TOL or moved > PARITY_TOL:
            raise ModelError(
                f"{model}: the new graph differs from the network by {worst:.2e} and from the shipped graph "
                f"by {moved:.2e} of the output range (> {PARITY_TOL}); nothing written"
            )
        with atomic_open(model, "wb") as handle:
            handle.write(new.read_bytes())
    before = heldout_sets(card)
    card.update(
        model_sha256=sha256_file(model),
        model_bytes=model.stat().st_size,
        parity=parity,
        exported=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        reexported={
            "from": f"{model.stem}.pt",
            "shipped_graph_difference": moved,
            "command": command_line("python scripts/reexport_model.py"),
        },
    )
    atomic_write_json(card_path(model), card)
    for name, entry in before.items():
        if "data" not in entry:
            continue  # suites are re-measured by `tactile-learn cards add --suite`
        data = entry["data"]
        folder = Path(str(data["path"]))
        if not (folder / "manifest.json").is_file():
            shard_size = int(data.get("shard_size") or DEFAULT_SHARD_SIZE)
            generate(load_scene(str(data["scene"])), int(data["n"]), int(data["seed"]), folder, shard_size=shard_size)
        # recorded as the CLI command that measures the same entry
        add_metrics(
            model, name, data=folder, command=f"tactile-learn cards add --model {model} --name {name} --data {folder}"
        )
    after = heldout_sets(read_card(model))
    return {"parity": parity, "shipped_graph_difference": moved, "before": before, "after": after}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("model", type=Path, help="a shipped model's .onnx (its .pt and .json beside it)")
    args = parser.parse_args(argv)
    report = reexport(args.model)
    print(f"parity {report['parity']}; shipped graph difference {report['shipped_graph_difference']:.2e}")
    for name, entry in report["after"].items():
        old = report["before"].get(name, {}).get("values", {})
        for key, value in entry.get("values", {}).items():
            if isinstance(value, float) and key in old:
                print(f"{name}.{key}: {old[key]!r} -> {value!r}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
