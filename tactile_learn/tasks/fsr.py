"""The FSR-film task (issue 5): six FSR readings -> contact position, force and presence.

Input ``readings`` (B, 6): ADC codes of sensors S0..S5 (layout in :mod:`synth.sensors.fsr`).

Prediction format ``estimate`` (B, 5) float32, the same for every method (classical and learned):

====  ============  =====================================================================
col   name          meaning
====  ============  =====================================================================
0     x_mm          contact centre, mm, origin at the film's centre
1     y_mm
2     force_n       applied force (N)
3     p_contact     probability (or 0/1 flag) that a contact is present
4     p_inside      probability (or 0 / 0.5 / 1 flag) that the contact lies inside the four
                    triangles, where position and force are trustworthy
5     p_one_press   1 if a detected contact is explained by one round press, 0 if not
                    (two simultaneous presses, a large flat indenter, ...: position and
                    force are then not to be trusted) or if no contact is detected; 0.5
                    where not checked (p_inside <= 0.5); see ``tactile_learn.fsr_check``
====  ============  =====================================================================

Columns 0-2 are meaningful only where ``p_contact > 0.5`` and ``p_one_press > 0.5``. Every method
computes columns 0-4 its own way; column 5 is the same check for all (``finish_prediction``).

Truth (generated datasets and user ``.npz`` files alike): ``xy_mm`` (B, 2) and ``force_n`` (B,);
``force_n == 0`` marks a frame without contact (its ``xy_mm`` is ignored; NaN is allowed there).

Metrics (plain floats; see :func:`fsr_metrics`), for three groups of frames:

- no suffix: contacts inside the triangles with forces in the paper's range
  (:data:`PAPER_FORCE_RANGE_N`), the conditions of the paper's figures (88.23 % force accuracy,
  2.5 mm spatial resolution, compared with ``force_accuracy`` and ``loc_err_mm_median``);
- ``_inside``: every contact inside the triangles (all forces);
- ``_film``: every contact anywhere on the film.

Calibration (``calibrate``): a few known presses on one film (``.npz`` with ``readings``,
``xy_mm``, ``force_n``; e.g. three presses on top of each sensor) give that film's six part gains
(least squares of measured against modelled conductance, per sensor, over the presses that load it
well above its break force). The result is a scene TOML: the input scene with ``[fsr.film] gains``
set. With such a scene every estimator's ``check_inputs`` maps the film's readings to those of the
nominal film (gain 1) before estimating, and ``generate --scene`` simulates that film.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from synth.config import dumps_toml
from synth.errors import DataError
from synth.io import atomic_write_text
from synth.scene import Scene
from synth.sensors import fsr
from tactile_learn.calibration.fsr_film import calibrate_gains, to_nominal_film
from tactile_learn.estimators.base import Estimator, prepared
from tactile_learn.tasks.base import EvalData, Task
from tactile_learn.validation.common import InputCheck, as_batch
from tactile_learn.validation.fsr import fsr_check

if TYPE_CHECKING:
    import torch

__all__ = [
    "COLUMNS",
    "PAPER_FORCE_RANGE_N",
    "FsrTask",
    "calibrate_gains",
    "fsr_metrics",
    "to_nominal_film",
]

#: the prediction's columns
COLUMNS: tuple[str, ...] = ("x_mm", "y_mm", "force_n", "p_contact", "p_inside", "p_one_press")
#: forces of the paper's own test conditions (its copy is cut before the experiments; the upper
#: decade of the FSR400's 0.1-10 N range, where test weights of 100 g to 1 kg sit)
PAPER_FORCE_RANGE_N: tuple[float, float] = (1.0, 10.0)
#: the paper's figures (seed 002)
PAPER_FORCE_ACCURACY = 0.8823
PAPER_SPATIAL_RESOLUTION_MM = 2.5


def _group_metrics(
    pred: np.ndarray, xy: np.ndarray, force: np.ndarray, contact: np.ndarray, mask: np.ndarray
) -> dict[str, float]:
    """Metrics over the frames of ``mask`` (contacts) plus every no-contact frame (detection)."""
    sel = mask & contact
    n = int(sel.sum())
    out: dict[str, float] = {"n_contacts": float(n)}
    det_frames = sel | ~contact
    detected = pred[:, 3] > 0.5
    out["detect_accuracy"] = (
        float(np.mean(detected[det_frames] == contact[det_frames])) if det_frames.any() else math.nan
    )
    if n == 0:
        for key in ("loc_err_mm_median", "loc_err_mm_p95", "force_err_pct_median", "force_accuracy"):
            out[key] = math.nan
        return out
    err = np.linalg.norm(pred[sel, :2].astype(np.float64) - xy[sel], axis=1)
    rel = np.abs(pred[sel, 2].astype(np.float64) - force[sel]) / force[sel]  # force > 0 on contact frames
    out["loc_err_mm_median"] = float(np.median(err))
    out["loc_err_mm_p95"] = float(np.percentile(err, 95))
    out["force_err_pct_median"] = float(100.0 * np.median(rel))
    out["force_accuracy"] = float(1.0 - np.mean(rel))
    return out


def fsr_metrics(pred: np.ndarray, xy_mm: np.ndarray, force_n: np.ndarray, layout: fsr.LayoutConfig) -> dict[str, Any]:
    """All fsr metrics of predictions (B, 5) against truth ``xy_mm`` (B, 2), ``force_n`` (B,).

    Position and force errors are over contact frames (whatever the method said about detection:
    a missed contact counts with its reported position and force); ``force_accuracy`` is the
    paper's ``1 - mean |F_est - F| / F``; ``detect_accuracy`` is over the group's contacts and every
    no-contact frame; ``inside_accuracy`` is how often ``p_inside > 0.5`` agrees with the truth
    over detected contacts on the whole film.
    """
    pred = np.asarray(pred, dtype=np.float64)
    if pred.ndim != 2 or pred.shape[1] != len(COLUMNS) or len(pred) != len(force_n):
        raise ValueError(f"prediction shape {pred.shape} does not match ({len(force_n)}, {len(COLUMNS)})")
    force = np.asarray(force_n, dtype=np.float64).reshape(-1)
    contact = force > 0
    xy = np.where(contact[:, None], np.nan_to_num(np.asarray(xy_mm, dtype=np.float64)), 0.0)
    inside = fsr.in_triangles(xy, layout) & contact
    lo, hi = PAPER_FORCE_RANGE_N
    paper = inside & (force >= lo) & (force <= hi)
    result: dict[str, Any] = {"n_frames": float(len(force))}
    for suffix, mask in (("", paper), ("_inside", inside), ("_film", contact)):
        for key, value in _group_metrics(pred, xy, force, contact, mask).items():
            result[f"{key}{suffix}"] = value
    detected = contact & (pred[:, 3] > 0.5)
    result["inside_accuracy"] = (
        float(np.mean((pred[detected, 4] > 0.5) == inside[detected])) if detected.any() else math.nan
    )
    # the one-press check: how often a detected press is flagged as not one round press
    flagged = detected & (pred[:, 5] < 0.5)
    result["flagged_rate"] = float(flagged.sum() / detected.sum()) if detected.any() else math.nan
    result["paper_force_accuracy"] = PAPER_FORCE_ACCURACY
    result["paper_spatial_resolution_mm"] = PAPER_SPATIAL_RESOLUTION_MM
    return result


class FsrTask(Task):
    name = "fsr"
    default_scene = "fsr6"
    input_key = "readings"
    output_key = "estimate"
    truth_keys = ("xy_mm", "force_n")
    primary_metric = ("loc_err_mm_median", False)
    net_sizes = ("small", "large")
    #: 200k frames x 20 epochs: about a minute on one core; a longer one-cycle schedule keeps the
    #: learning rate high for long and early stopping (patience 6) then cuts it short
    default_epochs = 20

    def input_shape(self, scene: Scene) -> tuple[int, ...]:
        return (fsr.N_SENSORS,)

    def input_check(self, scene: Scene) -> InputCheck:
        """:func:`~tactile_learn.validation.fsr.fsr_check`."""
        return fsr_check(scene.sensor)

    def fast_bounds(self, scene: Scene) -> tuple[float, float, bool] | None:
        return fsr_check(scene.sensor).bounds()

    def empty_prediction(self, n: int, scene: Scene) -> np.ndarray:
        """All six columns 0: no contact (``p_one_press`` 0 too, as for every undetected frame)."""
        return np.zeros((n, len(COLUMNS)), dtype=np.float32)

    def finish_prediction(self, inputs: np.ndarray, prediction: np.ndarray, scene: Scene) -> np.ndarray:
        """Append ``p_one_press`` (:class:`~tactile_learn.fsr_check.OnePressCheck`) to an estimate of
        the five other columns; an estimate that has it already is returned as it is."""
        from tactile_learn.fsr_check import with_one_press

        return with_one_press(inputs, prediction, scene)

    def prediction_finisher(self, scene: Scene) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
        """:meth:`finish_prediction` with the scene's one-press check built once (looking it up
        hashes the scene: at batch 1 that cost more than the network)."""
        from tactile_learn.fsr_check import one_press_check, with_one_press

        check = one_press_check(scene).prepare()
        return partial(with_one_press, scene=scene, check=check)

    def one_frame_finisher(self, scene: Scene) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
        """:meth:`prediction_finisher` for one frame in a model's bound buffers
        (:mod:`tactile_learn.onnx_one_frame`): ``finish(readings (1, 6), estimate (1, 5))`` gives a
        new (1, 6) estimate, ``p_one_press`` from the one-frame check on Python floats, as
        :func:`~tactile_learn.fsr_check.with_one_press` gives for one frame (bit for bit; tests)."""
        from tactile_learn.fsr_check import one_press_check

        p_one_press = one_press_check(scene).prepare().one_frame.p_one_press
        width = len(COLUMNS)

        def finish(readings: np.ndarray, estimate: np.ndarray) -> np.ndarray:
            out = np.empty((1, width), dtype=np.float32)
            out[0, :-1] = estimate[0]
            out[0, -1] = p_one_press(readings.tolist()[0], estimate.tolist()[0])
            return out

        return finish

    def classical_methods(self) -> dict[str, Callable[[Scene], Estimator]]:
        from tactile_learn.estimators.classical.triangulation import (
            FittedTriangulationEstimator,
            TriangulationEstimator,
        )

        return {
            "triangulation": prepared(TriangulationEstimator),
            "triangulation_fit": prepared(FittedTriangulationEstimator),
        }

    def load_eval_data(self, source: str | Path, scene: Scene | None = None) -> EvalData:
        path = Path(source)
        arrays, scene = self.read_arrays(path, scene)
        if not isinstance(scene.sensor, fsr.FsrConfig):
            raise DataError(f"scene {scene.name!r} is not an FSR-film scene")
        missing = [k for k in ("readings", "xy_mm", "force_n") if k not in arrays]
        if missing:
            raise DataError(
                f"{path}: needs arrays 'readings' (B, 6), 'xy_mm' (B, 2) and 'force_n' (B,); "
                f"missing {', '.join(missing)}"
            )
        for key in ("readings", "xy_mm", "force_n"):
            dtype = np.asarray(arrays[key]).dtype
            if not np.issubdtype(dtype, np.number) or np.issubdtype(dtype, np.complexfloating):
                raise DataError(f"{path}: {key} must be real numbers, got dtype {dtype}")
        readings = np.asarray(arrays["readings"])
        xy = np.asarray(arrays["xy_mm"], dtype=np.float64)
        force = np.asarray(arrays["force_n"], dtype=np.float64)
        n = len(readings)
        if readings.ndim != 2 or readings.shape[1] != fsr.N_SENSORS:
            raise DataError(f"{path}: readings have shape {readings.shape}, expected (B, {fsr.N_SENSORS})")
        if xy.shape != (n, 2):
            raise DataError(f"{path}: xy_mm has shape {xy.shape}, expected {(n, 2)}")
        if force.shape != (n,):
            raise DataError(f"{path}: force_n has shape {force.shape}, expected {(n,)}")
        if not np.isfinite(force).all() or (force < 0).any():
            raise DataError(f"{path}: force_n must be finite and >= 0 (0 marks a frame without contact)")
        if not np.isfinite(xy[force > 0]).all():
            raise DataError(f"{path}: xy_mm must be finite on frames with contact (force_n > 0)")
        extra = {k: np.asarray(v) for k, v in arrays.items() if k.startswith("latent_")}
        return EvalData(
            inputs=readings.astype(np.float32),
            truth={"xy_mm": np.nan_to_num(xy).astype(np.float32), "force_n": force.astype(np.float32)},
            scene=scene,
            extra=extra,
            source=str(path),
        )

    def metrics(self, pred: np.ndarray, data: EvalData) -> dict[str, Any]:
        result = fsr_metrics(pred, data.truth["xy_mm"], data.truth["force_n"], data.scene.sensor.layout)
        if "latent_n_presses" in data.extra and len(pred):
            result["flag_rates"] = _flag_rates(pred, data)
        return result

    def calibrate(self, source: str | Path, out: str | Path, scene: Scene) -> dict[str, Any]:
        """Gains of one film from a few known presses (``.npz``/dataset with readings, xy_mm,
        force_n); writes ``out`` (scene TOML with ``[fsr.film] gains``) and returns a summary."""
        data = self.load_eval_data(source, scene)
        config: fsr.FsrConfig = scene.sensor
        readings = as_batch(data.inputs, (fsr.N_SENSORS,), name="readings")
        force = data.truth["force_n"].astype(np.float64)
        press = force > 0
        if press.sum() < 1:
            raise DataError(f"{source}: no presses (force_n > 0) to calibrate from")
        gains, used = calibrate_gains(
            readings[press], data.truth["xy_mm"][press].astype(np.float64), force[press], config
        )
        if (used == 0).any():
            idle = ", ".join(f"S{i}" for i in np.flatnonzero(used == 0))
            raise DataError(
                f"{source}: no press loads {idle} well above its break force; press on top of every sensor "
                f"(e.g. 3 presses of 2-8 N on each of the six)"
            )
        film = dataclasses.replace(config.film, gains=tuple(round(float(g), 5) for g in gains), gain_spread=0.0)
        calibrated = dataclasses.replace(
            scene,
            name=f"{scene.name}_calibrated",
            sensor=dataclasses.replace(config, film=film),
            description=f"{scene.description} (film calibrated from {int(press.sum())} presses)".strip(),
        )
        atomic_write_text(out, _scene_toml(calibrated))
        return {
            "gains": [float(g) for g in gains],
            "presses_used_per_sensor": [int(u) for u in used],
            "n_presses": int(press.sum()),
            "scene": str(out),
        }

    # ---- learning (torch only inside) ---------------------------------------------------------------

    def fit_stats(self, arrays: dict[str, np.ndarray], scene: Scene) -> dict[str, Any]:
        from tactile_learn.nets.fsr import input_stats

        return input_stats(self._as_nominal(np.asarray(arrays["readings"]), scene), arrays["force_n"], scene)

    @staticmethod
    def _as_nominal(readings: np.ndarray, scene: Scene) -> np.ndarray:
        """Training sees what ``check_inputs`` hands the network: a calibrated film's readings are
        mapped to the nominal film's."""
        config: fsr.FsrConfig = scene.sensor
        if config.film.gains is None or not len(readings):
            return readings
        return to_nominal_film(readings, config, np.asarray(config.film.gains))

    def training_batch(
        self, arrays: dict[str, np.ndarray], scene: Scene, rng: np.random.Generator
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        readings = self._as_nominal(np.asarray(arrays["readings"], dtype=np.float32), scene)
        force = np.asarray(arrays["force_n"], dtype=np.float32).reshape(-1)
        xy = np.asarray(arrays["xy_mm"], dtype=np.float32)
        config: fsr.FsrConfig = scene.sensor
        contact = force > 0
        # the contact target is a contact the film can feel: some disc loaded to its break force
        # (a press far outside the triangles reads exactly like no press at all)
        tip = float(np.median(config.stimulus.tip_radii_mm))
        loads = fsr.sensor_loads(config, xy, np.where(contact, force, 0.0), np.full(len(force), tip))
        felt = contact & (loads.max(axis=1, initial=0.0) >= config.element.break_force_n)
        inside = fsr.in_triangles(xy.astype(np.float64), config.layout) & contact
        targets = {
            "xy_mm": np.where(contact[:, None], xy, 0.0).astype(np.float32),
            "log_force": np.log(np.where(contact, force, 1.0)).astype(np.float32),  # log(1) = 0 where masked
            "contact": felt.astype(np.float32),
            "position_weight": contact.astype(np.float32),
            "inside": inside.astype(np.float32),
        }
        return readings, targets

    def build_net(self, size: str, scene: Scene, stats: dict[str, Any]) -> torch.nn.Module:
        from tactile_learn.nets.fsr import build_fsr_net

        return build_fsr_net(size, scene, stats)

    def export_module(self, net: torch.nn.Module, scene: Scene) -> tuple[torch.nn.Module, list[str]]:
        """:class:`~tactile_learn.nets.fsr.FsrNet` is exported as
        :class:`~tactile_learn.nets.fsr_deploy.LeanFsrNet`: the same function in 21 ONNX nodes
        instead of 36 (features, normalisation and output scalings folded into three Gemms; ~25 % less
        per frame at batch 1 under onnxruntime)."""
        from tactile_learn.nets.fsr import FsrNet
        from tactile_learn.nets.fsr_deploy import LeanFsrNet

        return (LeanFsrNet(net) if isinstance(net, FsrNet) else net), [self.output_key]

    def train_forward(self, net: torch.nn.Module, inputs: torch.Tensor) -> torch.Tensor:
        return net.raw(inputs)  # type: ignore[operator]

    def loss(self, output: torch.Tensor, targets: dict[str, torch.Tensor]) -> torch.Tensor:
        from tactile_learn.nets.fsr import fsr_loss

        return fsr_loss(output, targets)


def _scene_toml(scene: Scene) -> str:
    header = "# Written by `tactile-learn calibrate --task fsr`: the film's part gains are in [fsr.film].\n"
    return header + dumps_toml(scene.to_dict())


def _flag_rates(pred: np.ndarray, data: EvalData) -> dict[str, float]:
    """Share of detected presses flagged (``p_one_press < 0.5``) per kind of frame: one round
    press (false flags), two presses, a flat indenter (detections)."""
    detected = pred[:, 3] > 0.5
    flagged = pred[:, 5] < 0.5
    two = data.extra["latent_n_presses"] >= 2
    flat = data.extra["latent_flat"].astype(bool)
    kinds = {"one_press": ~two & ~flat, "two_presses": two & ~flat, "flat_indenter": flat}
    out: dict[str, float] = {}
    for name, mask in kinds.items():
        sel = mask & detected
        out[f"{name}_flagged"] = float(flagged[sel].mean()) if sel.any() else math.nan
        out[f"{name}_n"] = float(sel.sum())
    return out
