"""The capacitive array task: calibrated cell loads -> force image and contact mask at 2x-4x the
taxel resolution.

Data: a press of ``F`` frames reads ``readings`` (F, N, M) volts; the front end
(:class:`~tactile_learn.calibration.capacitive.CapacitiveFrontEnd`, with the scene's calibration
table) turns whole presses into calibrated cell loads, whose single frames ``(N, M)`` in newtons
are what every method's ``predict`` takes (``input_key = "cell_load"``). Every method returns
``image`` (B, 2, N s, M s): the surface force (N per fine pixel) and the contact-mask probability.
Truth: ``force_image`` and ``contact_mask`` (F, N s, M s) per press; ``cell_load`` (F, N, M) the
true tab loads (the front end's reference metrics).

Evaluation data: a dataset folder from ``generate`` or an ``.npz`` with ``readings`` (B, F, N, M),
``force_image`` and ``contact_mask`` (B, F, N s, M s), optionally ``cell_load`` and the latents.
Metrics: :mod:`tactile_learn.contact_metrics` (IoU, centroid, orientation, by shape kind; the
separation of two nearby contacts); reference metrics (``--reference``): the calibrated cell-load
error against the true tab loads.

Calibration (``calibrate``): presses of known cell loads (``readings`` and ``cell_load``, e.g. a
``generate --scene capacitive8_rig`` dataset) fit the device's table
(:func:`~tactile_learn.calibration.capacitive.fit_calibration`); the output is the scene with its
``[capacitive.calibration]`` table set (comments of a shipped scene kept).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable
from functools import partial
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from synth.config import dumps_toml, to_dict
from synth.dataset import Dataset, load_arrays
from synth.errors import ConfigError, DataError
from synth.io import atomic_write_text
from synth.scene import Scene, load_scene, parse_scene
from synth.sensors.capacitive.config import G_TO_N, CalibrationTable, CapacitiveConfig
from tactile_learn.calibration.capacitive import CapacitiveFrontEnd, fit_calibration
from tactile_learn.contact_metrics import contact_metrics
from tactile_learn.estimators.base import Estimator, prepared
from tactile_learn.tasks.base import EvalData, Task
from tactile_learn.validation.capacitive import capacitive_input

if TYPE_CHECKING:
    import torch

__all__ = ["CapacitiveTask", "capacitive_config", "front_end_errors"]


def capacitive_config(scene: Scene) -> CapacitiveConfig:
    """The scene's capacitive array: its sensor, or the ``capacitive`` part of a combined sensor."""
    sensor = scene.sensor
    if isinstance(sensor, CapacitiveConfig):
        return sensor
    nested = getattr(sensor, "capacitive", None)
    if isinstance(nested, CapacitiveConfig):
        return nested
    raise DataError(f"scene {scene.name!r} has no capacitive array (task {scene.task!r})")


def front_end_errors(estimate: np.ndarray, truth: np.ndarray, full_scale_n: float) -> dict[str, Any]:
    """Cell-load errors in grams (median, p95 of |error|) over loaded cells (true load >= 5 % of
    the full scale), idle cells (< 1 g) and all cells, and as shares of the full scale."""
    err = np.abs(np.asarray(estimate, np.float64) - np.asarray(truth, np.float64)).ravel() / G_TO_N
    true = np.asarray(truth, np.float64).ravel()
    groups = {"loaded": true >= 0.05 * full_scale_n, "idle": true < G_TO_N, "all": np.ones(len(true), dtype=bool)}
    out: dict[str, Any] = {}
    for name, sel in groups.items():
        if sel.any():
            out[name] = {
                "median_g": float(np.median(err[sel])),
                "p95_g": float(np.percentile(err[sel], 95)),
                "n_cells": int(sel.sum()),
            }
    out["full_scale_g"] = full_scale_n / G_TO_N
    return out


class CapacitiveTask(Task):
    name = "capacitive"
    default_scene = "capacitive8"
    input_key = "cell_load"
    output_key = "image"
    truth_keys = ("force_image", "contact_mask")
    primary_metric = ("iou_mean", True)
    net_sizes = ("small", "large")
    default_epochs = 10
    stats_limit = 2000  # presses
    bench_samples = 250  # presses: 2,000 frames of capacitive8

    @property
    def train_keys(self) -> tuple[str, ...]:
        # training runs the front end on the raw readings (the dataset's ``cell_load`` is the truth)
        return ("readings", *self.truth_keys)

    def input_shape(self, scene: Scene) -> tuple[int, ...]:
        g = capacitive_config(scene).geometry
        return (g.n_rows, g.n_cols)

    def input_check(self, scene: Scene) -> Callable[[Any], np.ndarray]:
        """Calibrated cell loads (:func:`~tactile_learn.validation.capacitive.capacitive_input`)."""
        return partial(capacitive_input, config=capacitive_config(scene), quantity="cell_load")

    def fast_bounds(self, scene: Scene) -> tuple[float, float, bool] | None:
        # capacitive_input's cell_load check: finite, not below a tenth of the full scale under zero
        return -0.1 * float(capacitive_config(scene).readout.full_scale_n), float("inf"), False

    def empty_prediction(self, n: int, scene: Scene) -> np.ndarray:
        return np.zeros((n, 2, *capacitive_config(scene).geometry.image_shape), dtype=np.float32)

    def classical_methods(self) -> dict[str, Callable[[Scene], Estimator]]:
        from tactile_learn.estimators.classical.capacitive import BicubicEstimator, DeconvolutionEstimator

        return {"bicubic": prepared(BicubicEstimator), "deconvolution": prepared(DeconvolutionEstimator)}

    # ---- data ------------------------------------------------------------------------------------

    def front_end(self, scene: Scene) -> CapacitiveFrontEnd:
        return CapacitiveFrontEnd(capacitive_config(scene))

    def example_inputs(self, arrays: dict[str, np.ndarray], scene: Scene) -> np.ndarray:
        """Calibrated loads of every frame of the presses' ``readings``: (B F, N, M)."""
        loads = self.front_end(scene).loads(arrays["readings"])
        return loads.reshape(-1, *loads.shape[2:])

    def load_eval_data(self, source: str | Path, scene: Scene | None = None) -> EvalData:
        path = Path(source)
        arrays, scene = self.read_arrays(path, scene)
        return self.eval_data(arrays, scene, str(path))

    def eval_data(self, arrays: dict[str, np.ndarray], scene: Scene, source: str = "<arrays>") -> EvalData:
        """Evaluation frames from a dataset's arrays (presses through the scene's front end)."""
        path = source
        config = capacitive_config(scene)
        g = config.geometry
        missing = [k for k in ("readings", "force_image", "contact_mask") if k not in arrays]
        if missing:
            raise DataError(
                f"{path}: needs arrays 'readings' (B, F, N, M), 'force_image' and 'contact_mask' (B, F, N s, M s); "
                f"missing {', '.join(missing)}"
            )
        readings = np.asarray(arrays["readings"])
        if readings.ndim != 4 or readings.shape[2:] != (g.n_rows, g.n_cols):
            raise DataError(
                f"{path}: readings have shape {readings.shape}, scene {scene.name!r} reads presses (B, F, "
                f"{g.n_rows}, {g.n_cols}) (pass --scene for another array)"
            )
        b, f = readings.shape[:2]
        image = (b, f, *g.image_shape)
        for key in ("force_image", "contact_mask"):
            if np.shape(arrays[key]) != image:
                raise DataError(f"{path}: {key} has shape {np.shape(arrays[key])}, expected {image}")
        loads = self.front_end(scene).loads(readings)
        extra: dict[str, np.ndarray] = {
            "press": np.repeat(np.arange(b), f),
            "frame": np.tile(np.arange(f), b),
        }
        if "cell_load" in arrays:
            extra["true_cell_load"] = np.asarray(arrays["cell_load"], dtype=np.float32).reshape(
                b * f, g.n_rows, g.n_cols
            )
        if "latent_kind" in arrays and "latent_load" in arrays:
            present = np.asarray(arrays["latent_kind"])[:, None, :]  # (B, 1, K)
            touching = (np.asarray(arrays["latent_load"]) > 0) & (present >= 0)  # (B, F, K)
            kind = np.where(touching, present, -1)
            extra["kind"] = kind.reshape(b * f, -1).astype(np.int64)
            extra["n_contacts"] = touching.sum(axis=2).reshape(-1)
        return EvalData(
            inputs=loads.reshape(b * f, g.n_rows, g.n_cols),
            truth={
                "force_image": np.asarray(arrays["force_image"], dtype=np.float32).reshape(b * f, *g.image_shape),
                "contact_mask": np.asarray(arrays["contact_mask"], dtype=bool).reshape(b * f, *g.image_shape),
            },
            scene=scene,
            extra=extra,
            source=source,
        )

    def metrics(self, pred: np.ndarray, data: EvalData) -> dict[str, Any]:
        return contact_metrics(
            pred,
            data.truth["force_image"],
            data.truth["contact_mask"],
            capacitive_config(data.scene).geometry.h_mm,
            kind=data.extra.get("kind"),
            n_contacts=data.extra.get("n_contacts"),
        )

    def reference_metrics(self, data: EvalData, limit: int | None = None) -> dict[str, Any]:
        """The front end's calibrated cell-load error against the true tab loads (grams)."""
        if "true_cell_load" not in data.extra:
            return {}
        n = len(data) if limit is None else min(limit, len(data))
        full = capacitive_config(data.scene).readout.full_scale_n
        return {"cell_load_error": front_end_errors(data.inputs[:n], data.extra["true_cell_load"][:n], full)}

    # ---- calibration -----------------------------------------------------------------------------

    def calibrate(self, source: str | Path, out: str | Path, scene: Scene) -> dict[str, Any]:
        """Fit the device's table from presses of known cell loads; write ``scene`` with it to ``out``."""
        config = capacitive_config(scene)
        path = Path(source)
        if path.is_dir():
            dataset = Dataset(path)
            data_config = capacitive_config(dataset.scene)
            if _device_dict(data_config) != _device_dict(config):
                raise DataError(
                    f"{path}: the presses come from another device or array design than scene {scene.name!r} "
                    f"(device seed {data_config.device.seed} vs {config.device.seed}; geometry, cover, dielectric "
                    "and readout must match too)"
                )
            arrays = dataset.arrays(["readings", "cell_load"])
        else:
            arrays = load_arrays(path)
        missing = [k for k in ("readings", "cell_load") if k not in arrays]
        if missing:
            raise DataError(
                f"{path}: calibration needs 'readings' (B, F, N, M) and the known tab loads 'cell_load' (B, F, N, M); "
                f"missing {', '.join(missing)}"
            )
        table, summary = fit_calibration(arrays["readings"], arrays["cell_load"], config)
        calibrated = _with_calibration(scene, table, Path(out).stem)
        text = _scene_text(scene, calibrated, table)
        atomic_write_text(out, text)
        try:
            again = load_scene(Path(out))
        except ConfigError as exc:  # pragma: no cover - a bug in the writer
            raise DataError(f"{out}: the calibrated scene does not validate ({exc})") from None
        if again.digest != calibrated.digest:  # pragma: no cover - a bug in the text edit
            atomic_write_text(out, _HEADER + dumps_toml(calibrated.to_dict()))
        return {"scene": str(out), **summary}

    # ---- learning --------------------------------------------------------------------------------

    def fit_stats(self, arrays: dict[str, np.ndarray], scene: Scene) -> dict[str, Any]:
        from tactile_learn.nets.capacitive import input_stats

        return input_stats(self.example_inputs(arrays, scene), arrays["force_image"])

    def training_batch(
        self, arrays: dict[str, np.ndarray], scene: Scene, rng: np.random.Generator
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Calibrated loads of every frame and its true images, each frame flipped and (on a square
        array) transposed at random: the cover, tabs and readout are symmetric, and calibrated loads
        no longer carry the device's per-cell differences. The mask loss's weights stress the gaps
        between nearby contacts (:func:`~tactile_learn.nets.capacitive.gap_weights`)."""
        loads = self.example_inputs(arrays, scene)
        g = capacitive_config(scene).geometry
        force = np.asarray(arrays["force_image"], dtype=np.float32).reshape(-1, *g.image_shape)
        mask = np.asarray(arrays["contact_mask"], dtype=np.float32).reshape(-1, *g.image_shape)
        n = len(loads)
        flips = rng.random((n, 3)) < 0.5
        if g.n_rows != g.n_cols:
            flips[:, 2] = False
        for sel, op in (
            (flips[:, 0], lambda a: a[:, ::-1, :]),
            (flips[:, 1], lambda a: a[:, :, ::-1]),
            (flips[:, 2], lambda a: a.transpose(0, 2, 1)),
        ):
            if sel.any():
                loads[sel], force[sel], mask[sel] = op(loads[sel]), op(force[sel]), op(mask[sel])
        from tactile_learn.nets.capacitive import gap_weights

        targets = {"force_image": force, "contact_mask": mask, "mask_weight": gap_weights(mask > 0.5)}
        return np.ascontiguousarray(loads), targets

    def build_net(self, size: str, scene: Scene, stats: dict[str, Any]) -> torch.nn.Module:
        from tactile_learn.nets.capacitive import build_capacitive_net

        return build_capacitive_net(size, scene, stats)

    def train_forward(self, net: torch.nn.Module, inputs: torch.Tensor) -> torch.Tensor:
        return net.raw(inputs)  # type: ignore[operator]

    def loss(self, output: torch.Tensor, targets: dict[str, torch.Tensor]) -> torch.Tensor:
        from tactile_learn.nets.capacitive import capacitive_loss

        force = targets["force_image"]
        scale = force[force > 0].pow(2).mean().sqrt().clamp_min(1e-6) if bool((force > 0).any()) else force.sum() + 1
        return capacitive_loss(output, force, targets["contact_mask"], float(scale), targets.get("mask_weight"))


_HEADER = (
    "# Written by `tactile-learn calibrate --task capacitive`: the device's fitted response is the calibration table.\n"
)


def _device_dict(config: CapacitiveConfig) -> dict[str, Any]:
    """What must match between calibration presses and the scene they calibrate."""
    data = to_dict(config)
    for key in ("stimuli", "calibration", "hysteresis"):
        data.pop(key)
    return dict(data)


def _section(scene: Scene) -> str:
    """The calibration table's TOML header in ``scene`` ("capacitive.calibration", ...)."""
    sensor = scene.sensor
    prefix = scene.task if isinstance(sensor, CapacitiveConfig) else f"{scene.task}.capacitive"
    return f"{prefix}.calibration"


def _with_calibration(scene: Scene, table: CalibrationTable, name: str) -> Scene:
    config = dataclasses.replace(capacitive_config(scene), calibration=table)
    sensor = (
        config if isinstance(scene.sensor, CapacitiveConfig) else dataclasses.replace(scene.sensor, capacitive=config)
    )
    return parse_scene({**scene.to_dict(), "name": name, scene.task: to_dict(sensor)}, name)


def _scene_text(original: Scene, calibrated: Scene, table: CalibrationTable) -> str:
    """The calibrated scene as TOML: a shipped scene's own text (its comments) with the calibration
    table replaced or appended, else the whole scene written out."""
    shipped = resources.files("synth") / "scenes" / f"{original.name}.toml"
    if shipped.is_file() and load_scene(original.name).digest == original.digest:
        text = shipped.read_text(encoding="utf-8")
        header = f"[{_section(original)}]"
        # drop an existing table: its header up to the next table header (or the end)
        text = re.sub(rf"\n*^{re.escape(header)}$.*?(?=^\[|\Z)", "\n", text, flags=re.S | re.M).rstrip("\n")
        text = re.sub(r'^name = ".*"$', f'name = "{calibrated.name}"', text, count=1, flags=re.M)
        return (
            text
            + "\n\n# Fitted by `tactile-learn calibrate --task capacitive`: this device's response.\n"
            + _table_toml(table, _section(original), capacitive_config(original).geometry.n_cols)
        )
    return _HEADER + dumps_toml(calibrated.to_dict())


def _table_toml(table: CalibrationTable, section: str, per_line: int) -> str:
    """The table with its per-cell lists one array row per line (TOML arrays may span lines)."""
    lines = [f"[{section}]"]
    for key, value in to_dict(table).items():
        if isinstance(value, list):
            rows = [", ".join(repr(float(v)) for v in value[i : i + per_line]) for i in range(0, len(value), per_line)]
            lines.append(f"{key} = [\n    " + ",\n    ".join(rows) + ",\n]")
        else:
            lines.append(dumps_toml({key: value}).strip())
    return "\n".join(lines) + "\n"
