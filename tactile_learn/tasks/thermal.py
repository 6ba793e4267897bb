"""The thermal fingertip task (issues 4 and 11): temperature curves -> material or class.

Input ``readings`` (B, W): one thermistor's temperatures (degC) over the last ``W = window_s * fs``
samples, ending "now"; the contact onset is somewhere inside (the 4 x 4 array is classified pixel
by pixel: every pixel's curve is one row). A scene whose ``channels`` also name the passive
thermistor takes (B, 2, W): heated, then passive, over the same samples. Output
``probabilities`` (B, K + 1): the scene's K classes (its user classes, e.g. metal and wood, else
its materials), then ``none`` (the pixel touches nothing).

Views by contact duration. A generated touch keeps its whole record (``readings`` (P, R), and
``passive``) and its onset; the view at duration ``d`` is the window that ends at the last sample
with ``t <= onset + d`` (padded on the left with the record's first sample if the record starts
later than the window); a view exists while the record, and the contact when its release is known,
lasts. :meth:`ThermalTask.evaluate` predicts every view ``d`` in :data:`DURATIONS_S` (or the
``durations`` it is given):

- ``accuracy``: class accuracy over pixels in contact, pooled over the views;
- ``accuracy_by_duration``, ``family_accuracy_by_duration``, ``contact_accuracy_by_duration``
  (keys ``"0.25"``, ``"0.5"``, ``"1.0"``, ``"2.0"``, ``"4.0"``); family = metal, stone/glass,
  polymer, wood, foam; contact accuracy = touching vs ``none`` over every pixel;
- ``confusion_pairs``: the most frequent (true, predicted) errors pooled over the views, with their
  nominal effusivities;
- ``per_material_accuracy``: per class at 1 s;
- ``by_group`` (with ``group_by``): all of the above per value of a touches.csv column.

The oracle (the physics fit given each pixel's true sensor parameters) is not an estimator (it
needs the truth): :func:`oracle_accuracy_by_duration` computes ``oracle_accuracy_by_duration`` for
the same data; ``eval``/``bench`` call it and add the key beside the method's metrics.

Evaluation data: a generated dataset folder, an ``.npz`` (``readings`` (B, R) or (B, P, R) in
degC at the scene's rate, ``passive`` alike when the scene reads it, labels ``latent_material``
(int index, -1 = none) or ``material`` (names), optional ``latent_onset_s``/``onset_s``), or a
recording directory (:mod:`tactile_learn.thermal_recordings`: the onset from touches.csv, else the
force column's half-plateau crossing, else the heated curve's departure).

The pieces: classes and labels (:mod:`.thermal_classes`), evaluation data and views
(:mod:`.thermal_data`), metrics and the oracle (:mod:`.thermal_metrics`), calibration
(:mod:`.thermal_calibrate`) and training batches (:mod:`.thermal_batches`); this module is the
:class:`ThermalTask` that ties them to the task interface, and re-exports their public names.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from synth.dataset import Dataset, load_arrays
from synth.errors import DataError
from synth.scene import Scene, load_scene
from tactile_learn.estimators.base import Estimator, prepared
from tactile_learn.tasks.base import EvalData, Task
from tactile_learn.tasks.thermal_batches import thermal_fit_stats, thermal_training_batch
from tactile_learn.tasks.thermal_calibrate import calibrate_thermal
from tactile_learn.tasks.thermal_classes import (
    NONE,
    Classes,
    channel_keys,
    class_names,
    classes_of,
    labels_from_materials,
    recording_labels,
    thermal_config,
)
from tactile_learn.tasks.thermal_data import eval_data_from_arrays, eval_data_from_recordings, view
from tactile_learn.tasks.thermal_metrics import (
    DURATIONS_S,
    confusion_pairs,
    duration_key,
    group_values,
    oracle_accuracy_by_duration,
    summarize_views,
    thermal_metrics,
)
from tactile_learn.thermal_signal import windows
from tactile_learn.validation.common import InputCheck
from tactile_learn.validation.thermal import thermal_check, thermal_input_shape

if TYPE_CHECKING:
    import torch

__all__ = [
    "DURATIONS_S",
    "NONE",
    "Classes",
    "ThermalTask",
    "channel_keys",
    "class_names",
    "classes_of",
    "labels_from_materials",
    "oracle_accuracy_by_duration",
    "recording_labels",
    "thermal_metrics",
    "view",
    "windows",
]


class ThermalTask(Task):
    name = "thermal"
    default_scene = "thermal"
    input_key = "readings"
    output_key = "probabilities"
    truth_keys = ("latent_material", "latent_onset_s", "latent_release_s")
    primary_metric = ("accuracy", True)
    net_sizes = ("tiny", "small", "medium", "large")
    default_epochs = 40
    stats_limit = 2000  # whole touches (16 pixels x a full record each): 2,000 are plenty
    bench_samples = 200  # touches: 3,200 pixel curves, each viewed at four contact durations

    def input_shape(self, scene: Scene) -> tuple[int, ...]:
        return thermal_input_shape(thermal_config(scene))

    def train_keys_for(self, scene: Scene) -> tuple[str, ...]:
        extra = tuple(c for c in thermal_config(scene).channels if c != "heated")
        return (*self.train_keys, *extra)

    def output_labels(self, scene: Scene) -> tuple[str, ...]:
        return class_names(scene)

    def input_check(self, scene: Scene) -> InputCheck:
        """:func:`~tactile_learn.validation.thermal.thermal_check`."""
        return thermal_check(thermal_config(scene))

    def fast_bounds(self, scene: Scene) -> tuple[float, float, bool] | None:
        return thermal_check(thermal_config(scene)).bounds()

    def example_inputs(self, arrays: dict[str, np.ndarray], scene: Scene) -> np.ndarray:
        """Estimator inputs from simulated dataset arrays (``readings`` (B, P, R) and the latents):
        every pixel's window at 1 s of contact, (B * P, W). (The generic machinery's probe and
        conformance inputs; ``arrays["readings"]`` itself is a whole record, not an input.)"""
        data = eval_data_from_arrays(arrays, scene, "<arrays>")
        return view(data, 1.0)[0]

    def latency_inputs(self, data: EvalData) -> np.ndarray:
        """One pixel's window at 1 s of contact per frame: what a deployed classifier is fed."""
        return view(data, 1.0)[0]

    def reference_metrics(self, data: EvalData, limit: int | None = None) -> dict[str, Any]:
        """Metrics that do not depend on the method: the oracle's (see
        :func:`oracle_accuracy_by_duration`); empty when ``data`` lacks the sensor's latents."""
        if "latent_heat_capacity_j_m2k" not in data.extra:
            return {}
        return oracle_accuracy_by_duration(data, limit)

    def classical_methods(self) -> dict[str, Callable[[Scene], Estimator]]:
        from tactile_learn.estimators.classical.calibrated_fit import CalibratedFitEstimator
        from tactile_learn.estimators.classical.curve_match import CurveMatchEstimator
        from tactile_learn.estimators.classical.physics_fit import PhysicsFitEstimator

        return {
            "curve_match": prepared(CurveMatchEstimator),
            "physics_fit": prepared(PhysicsFitEstimator),
            "calibrated": prepared(CalibratedFitEstimator),
        }

    # ---- evaluation data -----------------------------------------------------------------------

    def load_eval_data(self, source: str | Path, scene: Scene | None = None) -> EvalData:
        from tactile_learn.thermal_recordings import INDEX

        path = Path(source)
        if path.is_dir() and (path / INDEX).is_file():
            return eval_data_from_recordings(path, scene or load_scene(self.default_scene))
        if path.is_dir():
            dataset = Dataset(path)
            if dataset.scene.task != self.name:
                raise DataError(f"{path}: dataset is for task {dataset.scene.task!r}, not {self.name!r}")
            arrays = dataset.arrays()
            scene = scene or dataset.scene
        else:
            arrays = load_arrays(path)
            scene = scene or load_scene(self.default_scene)
        return eval_data_from_arrays(arrays, scene, str(path))

    # ---- metrics -------------------------------------------------------------------------------

    def metrics(self, pred: np.ndarray, data: EvalData) -> dict[str, Any]:
        classes = classes_of(thermal_config(data.scene))
        keep = data.extra.get("labelled", np.ones(len(data), dtype=bool))
        out = thermal_metrics(np.asarray(pred)[keep], data.truth["label"][keep], classes)
        out["confusion_pairs"] = confusion_pairs(out.pop("confusion"), classes)
        return out

    def evaluate(
        self,
        estimator: Estimator,
        data: EvalData,
        durations: Sequence[float] | None = None,
        group_by: str | None = None,
    ) -> dict[str, Any]:
        """Metrics of ``estimator`` on every duration view (see the module docstring); with
        ``group_by`` (a column of a recording's ``touches.csv``, or a latent of simulated data) the
        same metrics per value of that column under ``by_group``. The estimator (a classifier: its
        ``predict_proba`` is evaluated) is prepared here if it is not yet."""
        proba = estimator.prepare().predict_proba  # type: ignore[attr-defined]  # thermal methods all classify
        if "record" not in data.extra:
            return self.metrics(proba(data.inputs), data)
        return self.evaluate_by_duration(lambda d, x, rows: proba(x), data, durations, group_by)

    def evaluate_by_duration(
        self,
        predict: Callable[[float, np.ndarray, np.ndarray], np.ndarray],
        data: EvalData,
        durations: Sequence[float] | None = None,
        group_by: str | None = None,
    ) -> dict[str, Any]:
        """:meth:`evaluate` for any ``predict(duration_s, windows, rows)`` giving (n, K + 1) scores
        of the touches ``rows`` of ``data`` (their ``windows`` of that duration): a method that
        reads more than the windows (e.g. the force record) or has one model per duration."""
        durations = tuple(DURATIONS_S if durations is None else durations)
        groups = group_values(data, group_by) if group_by else None
        keep_all = data.extra.get("labelled", np.ones(len(data), dtype=bool))
        preds: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for d in durations:
            x, valid = view(data, d)
            keep = valid & keep_all
            if keep.any():
                rows = np.flatnonzero(keep)
                preds[duration_key(d)] = (rows, predict(d, x[keep], rows))
        result = summarize_views(data, preds, np.ones(len(data), dtype=bool))
        if groups is not None:
            result["by_group"] = {
                str(value): {"n_touches": int((groups == value).sum()), **summarize_views(data, preds, groups == value)}
                for value in sorted(set(groups.tolist()))
            }
        return result

    # ---- calibration ---------------------------------------------------------------------------

    def calibrate(
        self,
        source: str | Path,
        out: str | Path,
        scene: Scene,
        channels: str | None = None,
        class_map: dict[str, tuple[str, ...]] | None = None,
    ) -> dict[str, Any]:
        """Fit the user's sensor from labelled recordings; write a scene TOML for ``generate``
        (:func:`~tactile_learn.tasks.thermal_calibrate.calibrate_thermal`)."""
        return calibrate_thermal(source, out, scene, channels, class_map)

    # ---- learning (torch inside) ---------------------------------------------------------------

    def fit_stats(self, arrays: dict[str, np.ndarray], scene: Scene) -> dict[str, Any]:
        return thermal_fit_stats(arrays, scene)

    def training_batch(
        self, arrays: dict[str, np.ndarray], scene: Scene, rng: np.random.Generator
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """:func:`~tactile_learn.tasks.thermal_batches.thermal_training_batch`: windows of 4 random
        pixels of every touch at random contact durations, with a random offset."""
        return thermal_training_batch(arrays, scene, rng)

    def build_net(self, size: str, scene: Scene, stats: dict[str, Any]) -> torch.nn.Module:
        from tactile_learn.nets.thermal import build_thermal_net

        return build_thermal_net(size, scene, stats)

    def train_forward(self, net: torch.nn.Module, inputs: torch.Tensor) -> torch.Tensor:
        return net.logits(inputs)  # type: ignore[operator]

    def loss(self, output: torch.Tensor, targets: dict[str, torch.Tensor]) -> torch.Tensor:
        from tactile_learn.nets.thermal import thermal_loss

        return thermal_loss(output, targets["label"])
