"""Classifiers trained on a handful of labelled real touches alone (no simulator): the baselines
beside ``adapt`` on real recordings, and the heated-only classifier that holds when the press
speed changes between sessions.

``aligned_pca``: onset-aligned curves, PCA + shrunk linear discriminant
(:mod:`tactile_learn.estimators.classical.aligned_pca`); ``press_aligned``: curves read against
press time (the force's running integral), nearest labelled touch
(:mod:`tactile_learn.estimators.classical.press_aligned`). One model per duration of contact.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from synth.errors import ConfigError
from tactile_learn.estimators.classical.aligned_pca import AlignedPca, aligned_curves
from tactile_learn.estimators.classical.press_aligned import NearestTouch, press_aligned_features
from tactile_learn.tasks.base import EvalData
from tactile_learn.tasks.thermal import DURATIONS_S, ThermalTask, channel_keys
from tactile_learn.tasks.thermal_metrics import duration_key

__all__ = [
    "FEW_SHOT_METHODS",
    "few_shot_evaluate",
    "few_shot_features",
    "few_shot_predict",
    "labelled_mask",
    "leave_one_out",
]

FEW_SHOT_METHODS = ("aligned_pca", "press_aligned")


def _check(method: str) -> None:
    if method not in FEW_SHOT_METHODS:
        raise ConfigError(f"few-shot method {method!r} is not one of {', '.join(FEW_SHOT_METHODS)}")


def labelled_mask(data: EvalData) -> np.ndarray:
    """Which touches carry a label (recordings may hold unlabelled ones; simulated touches all do)."""
    return np.asarray(data.extra.get("labelled", np.ones(len(data), dtype=bool)), dtype=bool)


def few_shot_features(method: str, data: EvalData, duration_s: float) -> np.ndarray:
    """Features of every touch of ``data`` (recordings read by ``ThermalTask.load_eval_data``,
    every channel of its scene) read up to ``duration_s`` after the onset."""
    _check(method)
    fs = data.scene.sensor.readout.sampling_hz
    records = [data.extra[key] for key in channel_keys(data.scene.sensor)]
    onset = data.extra["onset_s"]
    if method == "aligned_pca":
        return aligned_curves(records, onset, fs, duration_s)
    if "press" not in data.extra:  # simulated touches carry no force record: clock time from the onset
        press, has_press = np.zeros_like(records[0]), np.zeros(len(data), dtype=bool)
    else:
        press, has_press = data.extra["press"], data.extra["has_press"]
    return press_aligned_features(records, press, has_press, onset, fs, duration_s)


def few_shot_predict(method: str, train: EvalData, data: EvalData, duration_s: float) -> np.ndarray:
    """Class probabilities (N, K) of the touches of ``data`` by ``method`` trained on the labelled
    touches of ``train`` (same scene), both read up to ``duration_s`` after their onsets."""
    _check(method)
    keep = labelled_mask(train)
    if not keep.any():
        raise ConfigError(f"{train.source}: no labelled touch to train the {method} classifier on")
    k = len(train.scene.sensor.class_names)
    model = AlignedPca() if method == "aligned_pca" else NearestTouch()
    model.fit(few_shot_features(method, train, duration_s)[keep], train.truth["label"][keep], k)
    return model.predict_proba(few_shot_features(method, data, duration_s))


def leave_one_out(method: str, train: EvalData, duration_s: float) -> float:
    """Accuracy of ``method`` on each labelled touch of ``train`` when trained on the others: how a
    user with one labelled session chooses a method (or its settings) without touching the rest."""
    labelled = np.flatnonzero(labelled_mask(train))
    if len(labelled) < 3:
        raise ConfigError(f"{train.source}: leave-one-out needs 3 or more labelled touches, got {len(labelled)}")
    right = []
    for i in labelled:
        others = train.subset(labelled[labelled != i])
        proba = few_shot_predict(method, others, train.subset(np.array([i])), duration_s)
        right.append(int(proba.argmax(axis=1)[0]) == int(train.truth["label"][i]))
    return float(np.mean(right))


def few_shot_evaluate(
    method: str,
    train: EvalData,
    data: EvalData,
    durations: Sequence[float] | None = None,
    group_by: str | None = None,
) -> dict[str, Any]:
    """``ThermalTask.evaluate``'s metrics (``accuracy_by_duration``, ``by_group``, ...) of ``method``
    trained on the labelled touches of ``train``, one model per duration, on the touches of
    ``data``; plus ``leave_one_out_by_duration`` on ``train`` (the user's own check)."""
    _check(method)
    if train.scene.sensor.class_names != data.scene.sensor.class_names:
        raise ConfigError("few-shot: the labelled touches and the touches to classify are read with different classes")

    def predict(duration_s: float, windows: np.ndarray, rows: np.ndarray) -> np.ndarray:
        proba = few_shot_predict(method, train, data.subset(rows), duration_s)
        return np.concatenate([proba, np.zeros((len(proba), 1))], axis=1)  # never "no contact"

    durations = tuple(DURATIONS_S if durations is None else durations)
    metrics = ThermalTask().evaluate_by_duration(predict, data, durations, group_by)
    metrics["leave_one_out_by_duration"] = {duration_key(d): leave_one_out(method, train, d) for d in durations}
    metrics["n_labelled"] = int(np.count_nonzero(labelled_mask(train)))
    return metrics
