"""The classifier ``adapt`` hands a user: whichever candidates the labelled session itself supports.

Why: on real recordings no single classifier holds whichever session is labelled. The network
trained on the calibrated simulator misses what the simulator does not model (the rig's own
timing: room-temperature wood called metal when another session is labelled); a classifier
trained on the labelled touches alone (:mod:`tactile_learn.few_shot`) learns that session's
presses. Only the labelled touches can say which to trust, so, per duration of contact:

- every candidate is scored on the labelled touches: the few-shot classifiers (``press_aligned``,
  ``aligned_pca``) by leave-one-out (each touch classified by a model trained on the others), the
  network by its accuracy on them (it never trained on them; they only chose its epoch);
- the classifier is the average of the probabilities of every candidate whose score equals the
  best. Nine touches score in steps of 1/9, so candidates often tie; where they do the session has
  no evidence for one over the other, and candidates that fail for different reasons (the
  simulator's gaps, one session's press timing) are wrong together less often than either alone.
  Averaging needs no tie-break order, which nothing in one labelled session could justify.

The choice is written into the adapt card (``classifier``: the scores and the members per
duration) and redone identically at evaluation (the same labelled touches, copied into the adapt
folder, give the same scores: the few-shot classifiers and the network are deterministic).
numpy and onnxruntime; no torch.
"""

from __future__ import annotations

import csv
import io
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from synth.errors import ConfigError, DataError
from synth.io import atomic_write_text
from tactile_learn.few_shot import FEW_SHOT_METHODS, _labelled, few_shot_predict, leave_one_out
from tactile_learn.tasks.base import EvalData
from tactile_learn.tasks.thermal import DURATIONS_S, ThermalTask
from tactile_learn.tasks.thermal_data import view
from tactile_learn.tasks.thermal_metrics import duration_key
from tactile_learn.thermal_recordings import INDEX, _read_text

__all__ = [
    "CANDIDATES",
    "LABELLED_FOLDER",
    "RULE",
    "candidate_scores",
    "choice_evaluate",
    "choice_predict",
    "choose",
    "copy_recordings",
    "load_adapted",
    "write_choice",
]

#: the network adapt trains, then the few-shot classifiers; the order only fixes how results are listed
CANDIDATES = ("network", *FEW_SHOT_METHODS)
#: where adapt keeps a copy of the labelled touches (the few-shot candidates learn from them at eval)
LABELLED_FOLDER = "labelled"
#: the rule in words, for the card
RULE = (
    "per duration: leave-one-out accuracy on the labelled touches for the few-shot classifiers, accuracy on "
    "them for the network (never trained on them); the probabilities of every candidate at the best score averaged"
)


class Classifier(Protocol):
    """What the network candidate must offer: class probabilities (N, K [+ 1]) of duration windows."""

    def predict_proba(self, x: np.ndarray) -> np.ndarray: ...


def _network_proba(network: Classifier, data: EvalData, duration_s: float, k: int) -> np.ndarray:
    x, valid = view(data, duration_s)
    if not valid.all():
        raise DataError(f"{data.source}: {int((~valid).sum())} touches end before {duration_s:g} s of contact")
    proba = np.asarray(network.predict_proba(x), dtype=np.float64)[:, :k]  # its "no contact" column dropped
    # renormalised over the user's classes; a row the network gives no class at all stays uniform
    total = proba.sum(axis=1, keepdims=True)
    return np.where(total > 0, proba / np.maximum(total, 1e-300), 1.0 / k)


def candidate_scores(train: EvalData, network: Classifier | None, duration_s: float) -> dict[str, float]:
    """Each candidate's score on the labelled touches of ``train`` at ``duration_s`` (module docstring);
    without a ``network`` the few-shot classifiers alone."""
    scores = {m: leave_one_out(m, train, duration_s) for m in FEW_SHOT_METHODS}
    if network is not None:
        keep = _labelled(train)
        k = len(train.scene.sensor.class_names)
        pred = _network_proba(network, train.subset(np.flatnonzero(keep)), duration_s, k).argmax(axis=1)
        scores["network"] = float(np.mean(pred == train.truth["label"][keep]))
    return {m: scores[m] for m in CANDIDATES if m in scores}


def choose(scores: dict[str, float]) -> list[str]:
    """Every candidate whose score equals the best (1e-9: the scores are fractions of one count)."""
    if not scores:
        raise ConfigError("no candidate classifier to choose from")
    best = max(scores.values())
    return [m for m, s in scores.items() if s >= best - 1e-9]


def choice_predict(
    members: Sequence[str], train: EvalData, data: EvalData, duration_s: float, network: Classifier | None
) -> np.ndarray:
    """The average of the members' class probabilities (N, K) for the touches of ``data``."""
    k = len(train.scene.sensor.class_names)
    parts = []
    for member in members:
        if member == "network":
            if network is None:
                raise ConfigError("the choice holds the network, but no network was given")
            parts.append(_network_proba(network, data, duration_s, k))
        else:
            parts.append(few_shot_predict(member, train, data, duration_s))
    return np.mean(parts, axis=0)


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
    choice: dict[str, dict[str, Any]] = {}
    for d in durations:
        scores = candidate_scores(train, network, d)
        choice[duration_key(d)] = {"scores": scores, "members": choose(scores)}

    def predict(duration_s: float, windows: np.ndarray, rows: np.ndarray) -> np.ndarray:
        members = choice[duration_key(duration_s)]["members"]
        proba = choice_predict(members, train, data.subset(rows), duration_s, network)
        return np.concatenate([proba, np.zeros((len(proba), 1))], axis=1)  # never "no contact"

    metrics = ThermalTask().evaluate_by_duration(predict, data, durations, group_by)
    metrics["choice_by_duration"] = choice
    return metrics


def copy_recordings(source: str | Path, target: str | Path) -> Path:
    """A self-contained copy of the recording folder ``source`` (its touches.csv and every touch
    file it names, flat under ``target``), so an adapt folder keeps the touches it learnt from."""
    folder, out = Path(source), Path(target)
    index = folder / INDEX
    if not index.is_file():
        raise DataError(f"{folder}: no {INDEX}")
    reader = csv.DictReader(io.StringIO(_read_text(index)))
    fields = list(reader.fieldnames or [])
    if "file" not in fields:
        raise DataError(f"{index}: no column 'file' (columns: {', '.join(fields)})")
    rows = list(reader)
    names = [Path(r["file"]).name for r in rows]
    if len(set(names)) != len(names):
        raise DataError(f"{index}: two touch files share a name; give each touch its own file name")
    out.mkdir(parents=True, exist_ok=True)
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    for row, name in zip(rows, names, strict=True):
        if not (folder / row["file"]).is_file():
            raise DataError(f"{index}: touch file {row['file']!r} does not exist")
        shutil.copyfile(folder / row["file"], out / name)  # an absolute name (a selection's index) stays absolute
        writer.writerow({**row, "file": name})
    atomic_write_text(out / INDEX, text.getvalue())  # last: a folder without it is no recording set
    return out


def write_choice(network: Classifier, labelled: str | Path, folder: str | Path, scene: Any) -> dict[str, Any]:
    """``adapt``'s last step: copy the labelled touches into ``folder``/labelled and return the card's
    ``classifier`` section (the rule, and per duration of :data:`DURATIONS_S` the scores and members)."""
    copy = copy_recordings(labelled, Path(folder) / LABELLED_FOLDER)
    train = ThermalTask().load_eval_data(copy, scene)
    by_duration = {}
    for d in DURATIONS_S:
        scores = candidate_scores(train, network, d)
        by_duration[duration_key(d)] = {"scores": scores, "members": choose(scores)}
    return {
        "rule": RULE,
        "labelled": LABELLED_FOLDER,
        "n_labelled": int(_labelled(train).sum()),
        "by_duration": by_duration,
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
