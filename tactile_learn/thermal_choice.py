"""The classifier ``adapt`` hands a user: whichever candidates the labelled session itself supports.

Why: on real recordings no single classifier holds whichever session is labelled. The network
trained on the calibrated simulator misses what the simulator does not model (the rig's own
timing: room-temperature wood called metal when another session is labelled); the calibrated
physical model fitted touch by touch (``calibrated``) misses other touches; a classifier trained on
the labelled touches alone (:mod:`tactile_learn.few_shot`) learns that session's presses. Only
the labelled touches can say which to trust, so, per duration of contact:

- every candidate is scored on the labelled touches: the few-shot classifiers (``press_aligned``,
  ``aligned_pca``) by leave-one-out (each touch classified by a model trained on the others), the
  network and the calibrated model by their accuracy on them (the network never trained on them,
  they only chose its epoch; the calibration was fitted to them: both scores lean optimistic);
- the members are every candidate whose score is within one labelled touch (1/n) of the best: the
  scores move in steps of 1/n, and one touch is within their noise (with n = 9 and a score of 0.9
  the binomial standard deviation is 0.1), so the session cannot rank candidates that close;
- the members vote, one vote each (their probabilities are on unlike scales: a softmax of distances
  to the nearest touch, a linear discriminant, a network, a fit's likelihood), a tie going to the
  class of the higher mean probability. The candidates rest on different evidence (the simulator,
  the physical model's fit, the labelled touches' shapes against clock time and against press
  time) and fail on different touches, so a majority corrects a single member's mistakes; a
  candidate the labelled touches show to be worse takes no part.

The choice is written into the adapt card (``classifier``: the scores and the members per
duration) and redone identically at evaluation (the same labelled touches, copied into the adapt
folder, give the same scores: the few-shot classifiers and the network are deterministic).
numpy and onnxruntime; no torch.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from synth.errors import ConfigError, DataError
from synth.scene import Scene
from tactile_learn.few_shot import FEW_SHOT_METHODS, few_shot_predict, labelled_mask, leave_one_out
from tactile_learn.tasks.base import EvalData
from tactile_learn.tasks.thermal import DURATIONS_S, ThermalTask
from tactile_learn.tasks.thermal_data import view
from tactile_learn.tasks.thermal_metrics import duration_key
from tactile_learn.thermal_recordings import INDEX, copy_recordings

__all__ = [
    "CANDIDATES",
    "LABELLED_FOLDER",
    "RULE",
    "WINDOW_CANDIDATES",
    "candidate_scores",
    "choice_by_duration",
    "choice_evaluate",
    "choice_predict",
    "choose",
    "copy_recordings",
    "load_adapted",
    "write_choice",
]

#: the network adapt trains, the calibrated model (both read duration windows: :data:`WINDOW_CANDIDATES`),
#: then the few-shot classifiers; the order only fixes how results are listed
WINDOW_CANDIDATES = ("network", "calibrated")
CANDIDATES = (*WINDOW_CANDIDATES, *FEW_SHOT_METHODS)
#: where adapt keeps a copy of the labelled touches (the few-shot candidates learn from them at eval)
LABELLED_FOLDER = "labelled"
#: the rule in words, for the card
RULE = (
    "per duration: leave-one-out accuracy on the labelled touches for the few-shot classifiers, accuracy on them "
    "for the network (never trained on them) and the calibrated model; every candidate within one labelled touch "
    "of the best score votes, a tie going to the higher mean probability"
)


class Classifier(Protocol):
    """What a window candidate offers: class probabilities (N, K [+ 1]) of duration windows."""

    def predict_proba(self, x: np.ndarray) -> np.ndarray: ...


def _window_proba(classifier: Classifier, data: EvalData, duration_s: float, k: int) -> np.ndarray:
    """A window classifier's probabilities (N, K) of the user's classes at ``duration_s``."""
    x, valid = view(data, duration_s)
    if not valid.all():
        raise DataError(f"{data.source}: {int((~valid).sum())} touches end before {duration_s:g} s of contact")
    proba = np.asarray(classifier.predict_proba(x), dtype=np.float64)[:, :k]  # its "no contact" column dropped
    # renormalised over the user's classes; a row given no class at all stays uniform
    total = proba.sum(axis=1, keepdims=True)
    return np.where(total > 0, proba / np.maximum(total, 1e-300), 1.0 / k)


def window_candidates(scene: Scene, network: Classifier | None) -> dict[str, Classifier]:
    """The candidates that read duration windows: the ``network`` (when given) and the calibrated
    physical model of ``scene`` (the classical ``calibrated`` method)."""
    out: dict[str, Classifier] = {} if network is None else {"network": network}
    out["calibrated"] = ThermalTask().classical_methods()["calibrated"](scene)  # type: ignore[assignment]
    return out


def candidate_scores(train: EvalData, network: Classifier | None, duration_s: float) -> dict[str, float]:
    """Each candidate's score on the labelled touches of ``train`` at ``duration_s`` (module
    docstring); without a ``network`` the others alone."""
    scores = {m: leave_one_out(m, train, duration_s) for m in FEW_SHOT_METHODS}
    keep = labelled_mask(train)
    k = len(train.scene.sensor.class_names)
    labelled = train.subset(np.flatnonzero(keep))
    for name, classifier in window_candidates(train.scene, network).items():
        pred = _window_proba(classifier, labelled, duration_s, k).argmax(axis=1)
        scores[name] = float(np.mean(pred == train.truth["label"][keep]))
    return {m: scores[m] for m in CANDIDATES if m in scores}


def choose(scores: dict[str, float], n_labelled: int) -> list[str]:
    """Every candidate whose score is within one of ``n_labelled`` touches of the best (module docstring)."""
    if not scores:
        raise ConfigError("no candidate classifier to choose from")
    if n_labelled < 1:
        raise ConfigError(f"choosing a classifier needs labelled touches, got {n_labelled}")
    best = max(scores.values())
    return [m for m, s in scores.items() if s >= best - 1.0 / n_labelled - 1e-9]  # 1e-9: fractions of counts


def choice_by_duration(
    train: EvalData, network: Classifier | None, durations: Sequence[float]
) -> dict[str, dict[str, Any]]:
    """Per duration (its key), the candidates' scores on the labelled touches of ``train`` and the
    members they choose (:func:`candidate_scores`, :func:`choose`)."""
    n = int(labelled_mask(train).sum())
    out = {}
    for d in durations:
        scores = candidate_scores(train, network, d)
        out[duration_key(d)] = {"scores": scores, "members": choose(scores, n)}
    return out


def choice_predict(
    members: Sequence[str], train: EvalData, data: EvalData, duration_s: float, network: Classifier | None
) -> np.ndarray:
    """Class scores (N, K) of the touches of ``data``: the members' votes plus their mean
    probability (below one vote, so it only breaks ties), normalised to sum to 1."""
    k = len(train.scene.sensor.class_names)
    if not members:
        raise ConfigError("the choice has no member")
    windows = window_candidates(train.scene, network)
    parts = []
    for member in members:
        if member in FEW_SHOT_METHODS:
            parts.append(few_shot_predict(member, train, data, duration_s))
        elif member in windows:
            parts.append(_window_proba(windows[member], data, duration_s, k))
        else:
            raise ConfigError(f"the choice holds {member!r}, which is not available here (no network given?)")
    votes = sum(np.eye(k)[p.argmax(axis=1)] for p in parts)
    score = votes + np.mean(parts, axis=0)
    return np.asarray(score / score.sum(axis=1, keepdims=True))


def choice_evaluate(
    train: EvalData,
    data: EvalData,
    network: Classifier | None,
    durations: Sequence[float] | None = None,
    group_by: str | None = None,
) -> dict[str, Any]:
    """``ThermalTask.evaluate``'s metrics of the choice on the touches of ``data``, redone per
    duration from the labelled touches of ``train``; plus ``choice_by_duration`` (scores, members)."""
    if train.scene.sensor.class_names != data.scene.sensor.class_names:
        raise ConfigError("the labelled touches and the touches to classify are read with different classes")
    durations = tuple(DURATIONS_S if durations is None else durations)
    choice = choice_by_duration(train, network, durations)

    def predict(duration_s: float, windows: np.ndarray, rows: np.ndarray) -> np.ndarray:
        members = choice[duration_key(duration_s)]["members"]
        proba = choice_predict(members, train, data.subset(rows), duration_s, network)
        return np.concatenate([proba, np.zeros((len(proba), 1))], axis=1)  # never "no contact"

    metrics = ThermalTask().evaluate_by_duration(predict, data, durations, group_by)
    metrics["choice_by_duration"] = choice
    return metrics


def write_choice(network: Classifier, labelled: str | Path, folder: str | Path, scene: Any) -> dict[str, Any]:
    """``adapt``'s last step: copy the labelled touches into ``folder``/labelled and return the card's
    ``classifier`` section (the rule, and per duration of :data:`DURATIONS_S` that every labelled
    touch's record reaches, the scores and members)."""
    copy = copy_recordings(labelled, Path(folder) / LABELLED_FOLDER)
    train = ThermalTask().load_eval_data(copy, scene)
    keep = labelled_mask(train)
    reached = [d for d in DURATIONS_S if view(train, d)[1][keep].all()]
    if not reached:
        raise DataError(f"{labelled}: no labelled touch's record reaches {min(DURATIONS_S):g} s after its onset")
    return {
        "rule": RULE,
        "labelled": LABELLED_FOLDER,
        "n_labelled": int(keep.sum()),
        "by_duration": choice_by_duration(train, network, reached),
    }


def load_adapted(spec: str | Path) -> tuple[Any, Path] | None:
    """``(network, labelled folder)`` when ``spec`` is an adapt output folder (its model.onnx's card
    holds a ``classifier``); None for anything else (a model file, a method name)."""
    from tactile_learn.runtime import OnnxEstimator, read_card

    folder = Path(spec)
    model = folder / "model.onnx"
    if not folder.is_dir() or not model.is_file():
        return None
    card = read_card(model)
    if "classifier" not in card:
        raise ConfigError(
            f"{folder}: its model's card holds no classifier choice (made by an older adapt): "
            f"evaluate {model} (the network alone) or run adapt again"
        )
    labelled = folder / str(card["classifier"]["labelled"])
    if not (labelled / INDEX).is_file():
        raise DataError(f"{folder}: the labelled touches adapt kept ({labelled.name}/{INDEX}) are missing")
    return OnnxEstimator(model, card=card).prepare(), labelled
