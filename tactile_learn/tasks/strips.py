"""The soft strip array task: N+M strip readings -> N x M intersection pressure map (kPa)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from synth.errors import DataError
from synth.scene import Scene
from synth.sensors.strips.config import StripsConfig
from tactile_learn.estimators.base import Estimator, prepared
from tactile_learn.metrics import strip_map_metrics
from tactile_learn.strips_guard import CHECK_OUTPUTS  # re-exported: its old home
from tactile_learn.tasks.base import EvalData, Task, readable_frames
from tactile_learn.validation.common import InputCheck
from tactile_learn.validation.strips import strips_check

if TYPE_CHECKING:
    import torch

__all__ = [
    "CHECK_OUTPUTS",
    "StripsTask",
    "crossing_pressure",
    "distinct_crossings",
    "frame_groups",
    "ghost_energy",
    "ghost_to_real",
    "pairing",
]


def _apart(extra: dict[str, np.ndarray], pitch_mm: float) -> np.ndarray:
    """Two contacts more than a pitch apart in both x and y: distinct rows and columns, so ghosts."""
    xy = extra["latent_xy_mm"][:, :2].astype(np.float64)
    if xy.shape[1] < 2:
        return np.zeros(len(xy), dtype=bool)
    return (np.abs(xy[:, 0, 0] - xy[:, 1, 0]) > pitch_mm) & (np.abs(xy[:, 0, 1] - xy[:, 1, 1]) > pitch_mm)


def frame_groups(extra: dict[str, np.ndarray], pitch_mm: float) -> dict[str, np.ndarray]:
    """Boolean masks of the ambiguity groups, from a dataset's latent contact list.

    - ``one_contact``: frames with exactly one contact;
    - ``two_distinct``: two contacts whose rows and columns can be paired: their forces or sizes
      differ by more than 15 %, or they share a row or column band (no ghost);
    - ``two_twins``: two near-identical contacts on distinct rows and columns: the two pairings give
      the same readings (to within noise), so no method can tell which diagonal is real.
    """
    n = extra["latent_n_contacts"].astype(int)
    groups = {"one_contact": n == 1}
    if extra["latent_force_n"].shape[1] < 2:
        groups["two_distinct"] = np.zeros_like(groups["one_contact"])
        groups["two_twins"] = np.zeros_like(groups["one_contact"])
        return groups
    force = extra["latent_force_n"][:, :2].astype(np.float64)
    radius = extra["latent_radius_mm"][:, :2].astype(np.float64)
    rel_f = np.abs(force[:, 0] - force[:, 1]) / np.maximum(force.max(axis=1), 1e-12)
    rel_r = np.abs(radius[:, 0] - radius[:, 1]) / np.maximum(radius.max(axis=1), 1e-12)
    similar = (rel_f < 0.15) & (rel_r < 0.15)
    apart = _apart(extra, pitch_mm)
    two = n == 2
    groups["two_twins"] = two & similar & apart
    groups["two_distinct"] = two & ~groups["two_twins"]
    return groups


def crossing_pressure(pred: np.ndarray, extra: dict[str, np.ndarray], pitch_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Per frame, the estimated pressure summed on the two real crossings of contacts 1 and 2
    (row 1, column 1) + (row 2, column 2), and on the two ghost crossings (row 1, column 2) +
    (row 2, column 1)."""
    n, m = pred.shape[1:]
    xy = extra["latent_xy_mm"][:, :2].astype(np.float64)
    rows = np.clip((xy[..., 1] // pitch_mm).astype(int), 0, n - 1)
    cols = np.clip((xy[..., 0] // pitch_mm).astype(int), 0, m - 1)
    b = np.arange(len(pred))
    real = pred[b, rows[:, 0], cols[:, 0]] + pred[b, rows[:, 1], cols[:, 1]]
    ghost = pred[b, rows[:, 0], cols[:, 1]] + pred[b, rows[:, 1], cols[:, 0]]
    return real, ghost


def ghost_to_real(real: np.ndarray, ghost: np.ndarray) -> np.ndarray:
    return np.asarray((ghost + 1e-9) / (real + 1e-9))  # 1e-9 kPa: an empty estimate counts as a spread, not 0/0


def ghost_energy(pred: np.ndarray, extra: dict[str, np.ndarray], pitch_mm: float) -> np.ndarray:
    """Per frame: the share of the map's total (its summed pressure) on the two ghost crossings."""
    _, ghost = crossing_pressure(pred, extra, pitch_mm)
    total = pred.reshape(len(pred), -1).sum(axis=1).astype(np.float64)
    # an empty map holds no ghost load: 0, not 0/0
    return np.divide(ghost, total, out=np.zeros_like(total), where=total > 0)


def distinct_crossings(extra: dict[str, np.ndarray], pitch_mm: float) -> np.ndarray:
    """Frames whose first two contacts are more than a pitch apart in x and y (two ghost crossings)."""
    return _apart(extra, pitch_mm)


def pairing(pred: np.ndarray, extra: dict[str, np.ndarray], pitch_mm: float) -> dict[str, float]:
    """How an estimate pairs the rows and columns of two contacts on distinct rows and columns.

    The two real crossings are (row of contact 1, column of contact 1) and (row 2, column 2); the
    ghosts are (row 1, column 2) and (row 2, column 1). With ``ratio`` = estimated pressure on the
    ghost crossings / on the real ones: ``confident_right`` (ratio < 0.5), ``spread`` (0.5 to 2:
    mass on both pairings, the honest answer when the readings cannot tell), ``confident_wrong``
    (ratio > 2: a pairing the readings do not support, invented).
    """
    real, ghost = crossing_pressure(pred, extra, pitch_mm)
    ratio = ghost_to_real(real, ghost)
    return {
        "ghost_to_real_median": float(np.median(ratio)) if len(ratio) else float("nan"),
        "confident_right": float(np.mean(ratio < 0.5)) if len(ratio) else float("nan"),
        "spread": float(np.mean((ratio >= 0.5) & (ratio <= 2.0))) if len(ratio) else float("nan"),
        "confident_wrong": float(np.mean(ratio > 2.0)) if len(ratio) else float("nan"),
    }


class StripsTask(Task):
    name = "strips"
    default_scene = "strips16"
    input_key = "readings"
    output_key = "pressure"
    truth_keys = ("pressure",)
    primary_metric = ("pearson_r_mean", True)
    net_sizes = (
        "small",
        "tiny",
        "large",
        "corrected",
        "wide",
        "wide_consistent",
        "deep",
        "small_law",
        "tiny_law",
        "large_law",
        "v1_small",
        "v1_large",
    )
    default_epochs = 12  # 400k mixed frames: about an hour on one busy core

    def input_shape(self, scene: Scene) -> tuple[int, ...]:
        """(C,): one reading per channel of the scene's layout (N + M for the orthogonal pair;
        ``synth.sensors.strip_layouts`` documents each layout's order)."""
        return (scene.sensor.wire_count(),)

    def input_layout(self, scene: Scene) -> dict[str, Any]:
        """The readings order of the scene's layout: each group of channels, its first index and count."""
        from synth.sensors.strips.layouts import StripLayout

        layout = StripLayout(scene.sensor.geometry)
        return {
            "layout": layout.name,
            "order": [{"group": g.name, "first": g.start, "count": g.stop - g.start} for g in layout.groups],
            "documented_in": "synth.sensors.strip_layouts",
        }

    def card_extras(self, model: Estimator, val: str | None, scene: Scene) -> dict[str, Any]:
        """``graph_optimization`` (onnxruntime's level for these networks) and ``consistency``: the
        flag thresholds of a model with the check outputs, a high quantile of each on the run's
        validation frames (in-distribution, never trained on)."""
        from tactile_learn.provenance import portable_path
        from tactile_learn.runtime import OnnxEstimator
        from tactile_learn.strips_guard import THRESHOLD_QUANTILE, calibrate_threshold

        # onnxruntime's NCHWc rewrite slows these small convolutions at batch 1 (tactile_learn.runtime)
        runtime = {"graph_optimization": "extended"}
        if not isinstance(model, OnnxEstimator) or val is None:
            return runtime
        if not set(CHECK_OUTPUTS) <= {o["name"] for o in model.card_["outputs"]}:
            return runtime
        # frames the sensor cannot read (a saturated ADC) have no residual to calibrate on
        data, _ = readable_frames(self, self.load_eval_data(val).subset(slice(0, 20000)))
        outputs = model.predict_all(data.inputs)
        definition = "tactile_learn.strips_consistency: residual_sigma (cell-constant pressure, unit gains) and balance"
        if str(model.card_.get("network", {}).get("size", "")).endswith("_consistent"):
            # the network's map takes one step through the forward model (nets.strips_consistent); the
            # graph reports the residual of the map before the step (the step's own model loads)
            definition += "; residual of the network's map before its consistency step (pressure: after it)"
        return {
            **runtime,
            "consistency": {
                "definition": definition,
                "thresholds": {k: calibrate_threshold(outputs[k], THRESHOLD_QUANTILE) for k in CHECK_OUTPUTS},
                "quantile": THRESHOLD_QUANTILE,
                "calibrated_on": {
                    "data": portable_path(val),
                    "frames": len(data),
                    **{f"{k}_median": float(np.median(outputs[k])) for k in CHECK_OUTPUTS},
                },
                "fallback": "intersection",
            },
        }

    def same_sensor(self, a: Scene, b: Scene) -> bool:
        """Same strip array (geometry, cover, piezoresistance, readout, noise), whatever is pressed."""

        def sensor(scene: Scene) -> dict[str, Any]:
            data = scene.to_dict()
            data[self.name] = {k: v for k, v in data[self.name].items() if k != "stimuli"}
            return {k: v for k, v in data.items() if k not in ("name", "description", "outputs")}

        return a.task == b.task == self.name and sensor(a) == sensor(b)

    def input_check(self, scene: Scene) -> InputCheck:
        """:func:`~tactile_learn.validation.strips.strips_check`."""
        return strips_check(scene.sensor)

    def fast_bounds(self, scene: Scene) -> tuple[float, float, bool] | None:
        return strips_check(scene.sensor).bounds()

    def one_frame_finisher(self, scene: Scene) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
        """The prediction of one frame in a model's bound buffers (:mod:`tactile_learn.onnx_one_frame`):
        the map as the graph wrote it (the task finishes nothing), copied out of the buffer."""
        return _copy_of_map

    def empty_prediction(self, n: int, scene: Scene) -> np.ndarray:
        g = scene.sensor.geometry
        return np.zeros((n, g.n_rows, g.n_cols), dtype=np.float32)

    def classical_methods(self) -> dict[str, Callable[[Scene], Estimator]]:
        from tactile_learn.estimators.classical.intersection import IntersectionEstimator
        from tactile_learn.estimators.classical.projection import ProjectionEstimator

        return {"intersection": prepared(IntersectionEstimator), "projection": prepared(ProjectionEstimator)}

    def load_eval_data(self, source: str | Path, scene: Scene | None = None) -> EvalData:
        path = Path(source)
        arrays, scene = self.read_arrays(path, scene)
        if not isinstance(scene.sensor, StripsConfig):
            raise DataError(f"scene {scene.name!r} is not a strip-array scene")
        for key in ("readings", "pressure"):
            if key not in arrays:
                raise DataError(f"{path}: needs arrays 'readings' (B, N+M) and 'pressure' (B, N, M); missing {key!r}")
        g = scene.sensor.geometry
        readings, pressure = arrays["readings"], arrays["pressure"]
        if readings.ndim != 2 or readings.shape[1] != self.input_shape(scene)[0]:
            raise DataError(
                f"{path}: readings have shape {readings.shape}, scene {scene.name!r} has "
                f"{self.input_shape(scene)[0]} readings ({g.n_rows}+{g.n_cols} strips, layout {g.layout!r}; "
                "pass --scene for another sensor)"
            )
        if pressure.shape != (len(readings), g.n_rows, g.n_cols):
            raise DataError(
                f"{path}: pressure has shape {pressure.shape}, expected {(len(readings), g.n_rows, g.n_cols)}"
            )
        extra = {k: v for k, v in arrays.items() if k.startswith("latent_")}
        return EvalData(inputs=readings, truth={"pressure": pressure}, scene=scene, extra=extra, source=str(path))

    def evaluate(self, estimator: Estimator, data: EvalData) -> dict[str, Any]:
        """Metrics of the estimate; for a general learned model (one with a readings residual and a
        flag threshold) also its ``flag`` report: how many frames it flags, how good its maps are on
        flagged and unflagged frames, and the metrics with the fallback on flagged frames. The
        estimator is prepared here if it is not yet."""
        estimator.prepare()
        checked = _checked_model(estimator)
        if checked is None:
            return self.metrics(estimator.predict(data.inputs), data)
        out = checked.check(data.inputs)
        result = self.metrics(out["learned"], data)
        result["flag"] = _flag_report(self, out, data, checked)
        return result

    def metrics(self, pred: np.ndarray, data: EvalData) -> dict[str, Any]:
        from tactile_learn.strips_consistency import StripConsistency

        pitch = data.scene.sensor.geometry.pitch_mm
        result = strip_map_metrics(pred, data.truth["pressure"], pitch)
        if len(data):
            # does the estimate explain the readings? (the same residual for every method)
            residual = StripConsistency(data.scene).residual(data.inputs, pred)
            result["residual_rel_median"] = float(np.median(residual["residual_rel"]))
            result["residual_rel_p95"] = float(np.percentile(residual["residual_rel"], 95))
            result["residual_sigma_median"] = float(np.median(residual["residual_sigma"]))
        if "latent_n_contacts" in data.extra and len(data):
            by_group = {}
            for group, mask in frame_groups(data.extra, pitch).items():
                if mask.any():
                    sub = strip_map_metrics(pred[mask], data.truth["pressure"][mask], pitch)
                    by_group[group] = {
                        "n_frames": int(mask.sum()),
                        **{k: sub[k] for k in ("pearson_r_mean", "pearson_r_median", "nrmse", "peak_err_mm_median")},
                    }
                    if group.startswith("two"):
                        apart = _apart(data.extra, pitch)[mask]
                        picked = {k: v[mask][apart] for k, v in data.extra.items()}
                        by_group[group]["pairing"] = pairing(pred[mask][apart], picked, pitch)
            result["by_group"] = by_group
        return result

    # ---- learning --------------------------------------------------------------------------------

    def fit_stats(self, arrays: dict[str, np.ndarray], scene: Scene) -> dict[str, Any]:
        from tactile_learn.nets.strips import input_stats

        return input_stats(arrays["readings"], arrays["pressure"], scene)

    def training_batch(
        self, arrays: dict[str, np.ndarray], scene: Scene, rng: np.random.Generator
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Readings and maps, each frame mirrored at random along y and/or x.

        Mirroring is an exact symmetry of the sensor (reverse the row strips' order and the map's
        rows, or the columns'), so it multiplies the data for free and teaches the position-specific
        layers that the array has no preferred side.
        """
        g = scene.sensor.geometry
        readings = arrays["readings"].astype(np.float32, copy=True)
        pressure = arrays["pressure"].astype(np.float32, copy=True)
        flip_y = rng.random(len(readings)) < 0.5
        flip_x = rng.random(len(readings)) < 0.5
        if g.layout != "orthogonal":
            return _mirrored(readings, pressure, flip_y, flip_x, scene), {"pressure": pressure}
        rows, cols = readings[:, : g.n_rows], readings[:, g.n_rows :]
        rows[flip_y] = rows[flip_y, ::-1]
        cols[flip_x] = cols[flip_x, ::-1]
        pressure[flip_y] = pressure[flip_y, ::-1, :]
        pressure[flip_x] = pressure[flip_x, :, ::-1]
        return readings, {"pressure": pressure}

    def build_net(self, size: str, scene: Scene, stats: dict[str, Any]) -> torch.nn.Module:
        from tactile_learn.nets.strips import build_strip_net

        return build_strip_net(size, scene, stats)

    def export_module(self, net: torch.nn.Module, scene: Scene) -> tuple[torch.nn.Module, list[str]]:
        """A general network (architecture 2) is exported with two more outputs per frame
        (:data:`CHECK_OUTPUTS`): the readings residual of its map and the readings' balance."""
        import torch

        from synth.dataset import simulate_shard
        from tactile_learn.nets.strips_deploy import deploy
        from tactile_learn.nets.strips_general import GeneralStripNet, GeneralStripNetWithResidual

        if not isinstance(net, GeneralStripNet):
            return net, [self.output_key]
        g = scene.sensor.geometry
        if net.correct or g.n_rows != g.n_cols:
            return GeneralStripNetWithResidual(net, scene), [self.output_key, *CHECK_OUTPUTS]
        # the same function with fewer graph nodes (checked against the trained module on these frames)
        probe = torch.from_numpy(simulate_shard(scene, 12345, 0, 256)["readings"])
        return deploy(net, scene, probe), [self.output_key, *CHECK_OUTPUTS]

    def train_forward(self, net: torch.nn.Module, inputs: torch.Tensor) -> Any:
        """The general network's final and intermediate maps (both supervised); else ``net(x)``."""
        outputs = getattr(net, "train_outputs", None)
        return outputs(inputs) if outputs is not None else net(inputs)

    def loss(self, output: Any, targets: dict[str, torch.Tensor], r_weight: float = 1.0) -> torch.Tensor:
        """``strip_loss``; ``r_weight`` (``train --r-weight``) weighs its per-frame (1 - r) term."""
        from tactile_learn.nets.strips import strip_loss

        return strip_loss(output, targets["pressure"], r_weight)


def _mirrored(
    readings: np.ndarray, pressure: np.ndarray, flip_y: np.ndarray, flip_x: np.ndarray, scene: Scene
) -> np.ndarray:
    """Mirror frames of any layout in place (maps) and by channel permutation (readings); a mirror
    that is no symmetry of the layout (a +45 diagonal layer alone under one flip) is replaced by the
    half-turn (both flips), which is one for every layout."""
    from synth.sensors.strips.layouts import StripLayout

    layout = StripLayout(scene.sensor.geometry)
    perms = {(fy, fx): layout.flip_permutation(fy, fx) for fy in (False, True) for fx in (False, True)}
    for (fy, fx), perm in perms.items():
        sel = (flip_y == fy) & (flip_x == fx)
        if not (fy or fx) or not sel.any():
            continue
        if perm is None:  # the half-turn maps every layout onto itself
            perm, fy, fx = perms[(True, True)], True, True
        if perm is not None:
            readings[sel] = readings[sel][:, perm]
            pressure[sel] = pressure[sel][:, :: -1 if fy else 1, :: -1 if fx else 1]
    return readings


def _checked_model(estimator: Estimator) -> Any:
    """The estimator as a :class:`~tactile_learn.strips_guard.CheckedStripModel` when it is one, or
    an ONNX model whose card carries a flag threshold; else ``None``."""
    from tactile_learn.runtime import OnnxEstimator
    from tactile_learn.strips_guard import CheckedStripModel

    if isinstance(estimator, CheckedStripModel):
        return estimator
    if isinstance(estimator, OnnxEstimator):
        card = estimator.card_
        has_outputs = set(CHECK_OUTPUTS) <= {o["name"] for o in card["outputs"]}
        if has_outputs and "thresholds" in card.get("consistency", {}):
            return CheckedStripModel(estimator).prepare()
    return None


def _flag_report(task: StripsTask, out: dict[str, np.ndarray], data: EvalData, checked: Any) -> dict[str, Any]:
    from tactile_learn.metrics import pearson_per_frame

    flagged = out["flagged"]
    r = pearson_per_frame(out["learned"], data.truth["pressure"])

    def mean_r(mask: np.ndarray) -> float:
        values = r[mask & np.isfinite(r)]
        return float(values.mean()) if values.size else float("nan")

    with_fallback = strip_map_metrics(out["pressure"], data.truth["pressure"], data.scene.sensor.geometry.pitch_mm)
    return {
        "thresholds": dict(checked.thresholds_),
        "fallback": str(
            checked.fallback if isinstance(checked.fallback, str) or checked.fallback is None else checked.fallback.name
        ),
        "flagged_share": float(flagged.mean()) if len(flagged) else float("nan"),
        "residual_median": float(np.median(out["residual"])) if len(flagged) else float("nan"),
        "pearson_r_mean_unflagged": mean_r(~flagged),
        "pearson_r_mean_flagged": mean_r(flagged),
        "with_fallback": {k: with_fallback[k] for k in ("pearson_r_mean", "nrmse")},
    }


def _copy_of_map(readings: np.ndarray, pressure: np.ndarray) -> np.ndarray:
    return pressure.copy()
