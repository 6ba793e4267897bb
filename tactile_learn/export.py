"""Export a finished run to ONNX with a parity check and a model card.

``export(RUN, models/NAME.onnx)``:

1. rebuilds the task's network from ``RUN/model.pt`` (best epoch) in eval mode;
2. exports it with the torch dynamo exporter (opset :data:`OPSET`, dynamic batch axis), and embeds
   JSON metadata (task, scene digest, grid, normalisation, package version) in the graph;
3. checks parity: onnxruntime and torch agree to ``PARITY_TOL`` of the output range at batch 1 and
   7 on real inputs, or the export fails and nothing is written under the final names;
4. optionally evaluates the ONNX model on a held-out ``test`` dataset, so the card's metrics come
   with the command that measured them;
5. writes ``NAME.onnx``, ``NAME.json`` (the card) and ``NAME.pt`` (the torch weights, for the
   benchmark's torch-eager backend) atomically.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from synth import __version__
from synth.dataset import simulate_shard
from synth.errors import ModelError
from synth.io import atomic_open, atomic_write_json, sha256_file
from synth.scene import Scene
from tactile_learn.cards import dataset_entry
from tactile_learn.checkpoints import save_torch
from tactile_learn.idle import IDLE_KEYS, measure_idle_floor
from tactile_learn.provenance import command_line, portable_path
from tactile_learn.runtime import CARD_FORMAT, METADATA_KEY, OnnxEstimator, card_path
from tactile_learn.tasks import get_task
from tactile_learn.tasks.base import Task
from tactile_learn.torch_estimator import TorchEstimator

__all__ = ["OPSET", "PARITY_TOL", "export", "parity_check", "portable_path", "to_onnx"]

OPSET = 18
#: max |onnx - torch| allowed, as a fraction of the torch output's range
PARITY_TOL = 1e-4


def _probe_inputs(task_name: str, scene: Scene, n: int, seed: int = 12345) -> np.ndarray:
    """Realistic inputs for the parity check: freshly simulated frames of the model's scene."""
    task = get_task(task_name)
    arrays = simulate_shard(scene, seed, 0, n)
    return task.check_inputs(task.example_inputs(arrays, scene), scene)


def _as_tuple(output: Any) -> tuple[torch.Tensor, ...]:
    return tuple(output) if isinstance(output, (tuple, list)) else (output,)


def parity_check(net: torch.nn.Module, onnx_path: Path, inputs: np.ndarray, threads: int = 1) -> dict[str, float]:
    """Max abs difference between torch and onnxruntime, at batch 1 and 7, relative to the range
    (the worst over the graph's outputs when it has several, and over the graph as the file holds it
    and as the runtime runs it, with :mod:`tactile_learn.onnx_fuse`'s rewrites)."""
    import onnxruntime as ort

    from tactile_learn.onnx_fuse import fused_model_bytes

    options = ort.SessionOptions()
    options.intra_op_num_threads = threads
    plain = Path(onnx_path).read_bytes()
    graphs = [plain]
    try:
        fused = fused_model_bytes(plain)
        graphs += [fused] if fused != plain else []
    except ImportError:  # no onnx package: the runtime runs the file's graph too
        pass
    sessions = [ort.InferenceSession(g, sess_options=options, providers=["CPUExecutionProvider"]) for g in graphs]
    name = sessions[0].get_inputs()[0].name
    report: dict[str, float] = {}
    for batch in (1, 7):
        x = inputs[:batch]
        with torch.inference_mode():
            expected_all = [e.numpy() for e in _as_tuple(net(torch.from_numpy(x)))]
        worst_abs, worst_rel = 0.0, 0.0
        for session in sessions:
            for expected, got in zip(expected_all, session.run(None, {name: x}), strict=True):
                span = float(expected.max() - expected.min()) or float(np.abs(expected).max()) or 1.0
                err = float(np.abs(got - expected).max())
                worst_abs, worst_rel = max(worst_abs, err), max(worst_rel, err / span)
        report[f"max_abs_err_b{batch}"] = worst_abs
        report[f"rel_err_b{batch}"] = worst_rel
    report["tolerance"] = PARITY_TOL
    return report


def export(
    run: str | Path,
    out: str | Path,
    *,
    name: str | None = None,
    test: str | Path | None = None,
    command: str | None = None,
    calibration: str | Path | None = None,
) -> dict[str, Any]:
    """Export ``run`` to ``out`` (``.onnx``) plus its card; returns the card."""
    out = Path(out)
    if out.suffix != ".onnx":
        raise ModelError(f"--out: {out} must end in .onnx")
    trained = TorchEstimator.from_checkpoint(run)
    saved, task, scene = trained.checkpoint, get_task(trained.task_name), trained.scene
    exported = _write_onnx(trained.net, task, scene, saved, out)
    card = _card(out, name, task, scene, saved, trained.net, exported)
    # the torch weights beside the ONNX file: bench's torch-eager backend and fine-tuning use them
    save_torch(
        out.with_suffix(".pt"),
        {"task": task.name, "size": saved["size"], "stats": saved["stats"], "state_dict": saved["state_dict"]},
    )
    # write the card first without held-out metrics, so the runtime can load the model to measure them
    atomic_write_json(card_path(out), card)
    calibrate_on = str(calibration) if calibration is not None else saved["result"]["config"].get("val")
    _add_card_extras(card, out, task, scene, calibrate_on)
    if test is not None:
        _add_heldout_metrics(card, out, task, test, command)
    return card


def _write_onnx(net: torch.nn.Module, task: Task, scene: Scene, saved: dict[str, Any], out: Path) -> dict[str, Any]:
    """The task's export graph written to ``out`` once it passes the parity check (nothing is written
    under ``out`` otherwise); returns the parity report, output names and shapes, and the metadata."""
    graph, output_names = task.export_module(net, scene)
    graph.eval()
    inputs = _probe_inputs(task.name, scene, 64)
    example = torch.from_numpy(inputs[:2])
    with torch.inference_mode():
        out_shapes = [list(o.shape[1:]) for o in _as_tuple(graph(example))]
    metadata = {
        "task": task.name,
        "scene_digest": scene.digest,
        "input_shape": list(task.input_shape(scene)),
        "output_shape": out_shapes[0],
        "normalisation": saved["stats"],
        "size": saved["size"],
        "package_version": __version__,
    }
    with tempfile.TemporaryDirectory(dir=out.parent if out.parent.exists() else None) as tmp:
        tmp_model = Path(tmp) / "model.onnx"
        to_onnx(graph, example, tmp_model, task.input_key, output_names, metadata)
        parity = parity_check(graph, tmp_model, inputs)
        worst = max(parity["rel_err_b1"], parity["rel_err_b7"])
        if worst > PARITY_TOL:
            raise ModelError(
                f"parity check failed: onnxruntime differs from torch by {worst:.2e} of the output range "
                f"(> {PARITY_TOL})"
            )
        out.parent.mkdir(parents=True, exist_ok=True)
        with atomic_open(out, "wb") as handle:
            handle.write(tmp_model.read_bytes())
    return {"parity": parity, "output_names": output_names, "out_shapes": out_shapes, "metadata": metadata}


def _card(
    out: Path,
    name: str | None,
    task: Task,
    scene: Scene,
    saved: dict[str, Any],
    net: torch.nn.Module,
    exported: dict[str, Any],
) -> dict[str, Any]:
    """The model card of the ONNX file ``out``: its interface, network, scene, training and validation."""
    result = saved["result"]
    return {
        "format": CARD_FORMAT,
        "name": name or out.stem,
        "task": task.name,
        "model_file": out.name,
        "model_sha256": sha256_file(out),
        "model_bytes": out.stat().st_size,
        "opset": OPSET,
        "package_version": __version__,
        "inputs": [
            {
                "name": task.input_key,
                "shape": ["batch", *exported["metadata"]["input_shape"]],
                "dtype": "float32",
                **task.input_layout(scene),
            }
        ],
        "outputs": [
            {"name": output, "shape": ["batch", *shape], "dtype": "float32"}
            for output, shape in zip(exported["output_names"], exported["out_shapes"], strict=True)
        ],
        "normalisation": saved["stats"],
        "network": {"size": saved["size"], "parameters": int(sum(p.numel() for p in net.parameters()))},
        "scene": scene.to_dict(),
        "scene_digest": scene.digest,
        "training": {
            "data": _card_data(result["train_data"]),
            "validation": {**result["val_data"], "path": portable_path(result["val_data"]["path"])},
            "epochs_run": result["epochs_run"],
            "best_epoch": result["best_epoch"],
            "train_seconds": result["train_seconds"],
            "threads": result["threads"],
            # a GPU-trained model is reproducible from its recipe, not bit for bit across devices
            "device": result["config"].get("device", "cpu"),
            "config": {
                k: _portable_paths(v) if k in ("data", "val", "out") and v else v for k, v in result["config"].items()
            },
            # weights averaged with another run's (scripts/average_weights.py): the run above is one of two
            **({"averaged": _card_averaged(result["averaged"])} if "averaged" in result else {}),
        },
        "parity": exported["parity"],
        "metrics": {"validation": result["val_metrics"]},
        "exported": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }


def _add_card_extras(card: dict[str, Any], out: Path, task: Task, scene: Scene, calibrate_on: str | None) -> None:
    """The task's own card entries, measured with the exported model (e.g. the strips flag
    thresholds, calibrated on the run's validation frames) and the sensor's idle noise floor."""
    extras = task.card_extras(OnnxEstimator(out).prepare(), calibrate_on, scene)
    if task.name in IDLE_KEYS:  # the sensor's noise floor at rest: the stream's idle gate
        extras["idle"] = measure_idle_floor(scene)
    if extras:
        card.update(extras)
        atomic_write_json(card_path(out), card)


def _add_heldout_metrics(card: dict[str, Any], out: Path, task: Task, test: str | Path, command: str | None) -> None:
    """Metrics of the exported model on the held-out dataset ``test``, with what regenerates it."""
    card["metrics"]["heldout"] = {**dataset_entry(task.name, out, test), "command": command or command_line()}
    atomic_write_json(card_path(out), card)


def _card_averaged(averaged: dict[str, Any]) -> dict[str, Any]:
    """A soup's provenance for the card: both runs (portable paths), the second's weight."""
    return {k: _portable_paths(v) if k in ("first", "second", "epochs") else v for k, v in averaged.items()}


def _portable_paths(paths: str | list[str] | tuple[str, ...]) -> str | list[str]:
    """A run's training data: one folder, or several read as one training set."""
    return portable_path(paths) if isinstance(paths, str) else [portable_path(p) for p in paths]


def _strip_debug_info(model: Any) -> None:
    """Drop the exporter's per-node stack traces and doc strings: they name source files of the
    machine that exported the model, and a shipped model must not carry them."""
    graphs = [model.graph, *(f for f in model.functions)]
    while graphs:
        graph = graphs.pop()
        for node in graph.node:
            del node.metadata_props[:]
            node.doc_string = ""
            for attr in node.attribute:
                if attr.g is not None and len(attr.g.node):
                    graphs.append(attr.g)
                graphs.extend(attr.graphs)
        for value in (*getattr(graph, "value_info", ()), *getattr(graph, "input", ()), *getattr(graph, "output", ())):
            del value.metadata_props[:]
        if hasattr(graph, "doc_string"):
            graph.doc_string = ""


def to_onnx(
    net: torch.nn.Module,
    example: torch.Tensor,
    path: Path,
    input_name: str,
    output_name: str | list[str],
    metadata: dict[str, Any],
) -> None:
    """Export ``net`` (eval mode) to ``path`` with the dynamo exporter: opset :data:`OPSET`, a
    dynamic batch axis, ``metadata`` as JSON under the ONNX metadata key, no exporter stack traces.
    ``output_name`` names the output, or each of a network returning a tuple."""
    import logging
    import warnings

    import onnx

    logging.getLogger("torch.onnx").setLevel(logging.ERROR)
    batch = torch.export.Dim("batch", min=1, max=1 << 20)
    with warnings.catch_warnings():
        # torch 2.13's exporter warns about its own deprecated internals (pytree's LeafSpec) while
        # decomposing: nothing the caller can change; the parity check afterwards verifies the graph
        warnings.simplefilter("ignore")
        program = torch.onnx.export(
            net,
            (example,),
            dynamo=True,
            input_names=[input_name],
            output_names=[output_name] if isinstance(output_name, str) else list(output_name),
            dynamic_shapes=({0: batch},),
            opset_version=OPSET,
            verbose=False,
        )
    if program is None:  # pragma: no cover - dynamo=True always returns a program
        raise ModelError("the ONNX exporter returned nothing")
    program.save(str(path))
    model = onnx.load(str(path))
    _strip_debug_info(model)
    entry = model.metadata_props.add()
    entry.key = METADATA_KEY
    entry.value = json.dumps(metadata)
    model.producer_name = "tactile-learn"
    onnx.checker.check_model(model)
    onnx.save(model, str(path))


def _card_data(train_data: dict[str, Any]) -> dict[str, Any]:
    """The card's record of the training data: a dataset's path made portable; a stream (training
    on simulated touches, no path) as it is."""
    if "path" not in train_data:
        return dict(train_data)
    return {**train_data, "path": _portable_paths(train_data["path"])}
