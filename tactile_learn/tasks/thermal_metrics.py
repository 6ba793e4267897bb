"""The thermal task's metrics: class, family and contact accuracy with confusion counts, the same
per contact duration (views) pooled and per group, and the oracle's accuracy by duration."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from synth.errors import DataError
from synth.materials import Material
from tactile_learn.tasks.base import EvalData
from tactile_learn.tasks.thermal_classes import NONE, Classes, classes_of, thermal_config
from tactile_learn.tasks.thermal_data import view

__all__ = [
    "DURATIONS_S",
    "confusion_pairs",
    "duration_key",
    "group_values",
    "oracle_accuracy_by_duration",
    "summarize_views",
    "thermal_metrics",
]

#: contact durations (s) of the evaluation views (``eval --durations`` chooses others)
DURATIONS_S: tuple[float, ...] = (0.25, 0.5, 1.0, 2.0, 4.0)


def thermal_metrics(pred: np.ndarray, labels: np.ndarray, materials: Sequence[Material] | Classes) -> dict[str, Any]:
    """Accuracy (class, over pixels in contact), family and contact accuracy, per-class accuracy
    and the confusion counts of predictions ``pred`` (B, K + 1) against ``labels`` (B,)."""
    classes = materials if isinstance(materials, Classes) else classes_of(materials)
    k = len(classes)
    guess = np.asarray(pred).argmax(axis=1) if len(pred) else np.zeros(0, dtype=np.int64)
    labels = np.asarray(labels).astype(np.int64)
    family = np.concatenate([classes.families, [-2]])
    contact = labels < k
    n = int(contact.sum())
    right = guess[contact] == labels[contact]
    out: dict[str, Any] = {
        "accuracy": float(right.mean()) if n else float("nan"),
        "family_accuracy": float((family[guess[contact]] == family[labels[contact]]).mean()) if n else float("nan"),
        "contact_accuracy": float(((guess < k) == contact).mean()) if len(labels) else float("nan"),
        "n_contact": n,
        "n_none": int((~contact).sum()),
    }
    per = {}
    for i, name in enumerate(classes.names):
        sel = labels == i
        if sel.any():
            per[name] = float((guess[sel] == i).mean())
    out["per_material_accuracy"] = per
    counts = np.zeros((k + 1, k + 1), dtype=np.int64)
    np.add.at(counts, (labels, guess), 1)
    out["confusion"] = counts
    return out


def confusion_pairs(counts: np.ndarray, materials: Sequence[Material] | Classes, top: int = 12) -> list[dict[str, Any]]:
    classes = materials if isinstance(materials, Classes) else classes_of(materials)
    names = [*classes.names, NONE]
    eff = [*classes.effusivity.tolist(), 0.0]
    totals = counts.sum(axis=1)
    pairs: list[dict[str, Any]] = []
    for i in range(len(classes)):
        for j in range(len(names)):
            if i != j and counts[i, j] > 0:
                pairs.append(
                    {
                        "true": names[i],
                        "predicted": names[j],
                        "count": int(counts[i, j]),
                        "rate": float(counts[i, j] / totals[i]),  # totals[i] >= counts[i, j] > 0
                        "effusivity_true": round(eff[i], 1),
                        "effusivity_predicted": round(eff[j], 1),
                    }
                )
    pairs.sort(key=lambda p: -p["count"])
    return pairs[:top]


def group_values(data: EvalData, column: str) -> np.ndarray:
    """The values of ``column`` per row: a touches.csv column of recordings, or a per-pixel array
    of simulated data (``latent_...``); a DataError lists what exists."""
    for key in (f"info:{column}", column, f"latent_{column}"):
        if key in data.extra:
            return np.asarray(data.extra[key]).astype(str)
    known = sorted(k[5:] for k in data.extra if k.startswith("info:")) + sorted(
        k for k in data.extra if k.startswith("latent_")
    )
    raise DataError(f"--group-by: {data.source} has no column {column!r} (available: {', '.join(known) or 'none'})")


def duration_key(d: float) -> str:
    """A duration's key in the metrics: ``"0.25"``, ``"1.0"``."""
    return f"{d:g}" if d != int(d) else f"{d:.1f}"


def summarize_views(
    data: EvalData, preds: dict[str, tuple[np.ndarray, np.ndarray]], rows: np.ndarray
) -> dict[str, Any]:
    """Metrics of the predictions ``preds`` (per duration key: the rows of ``data`` and their
    scores) on the rows selected by the mask ``rows``: pooled over the views and per view."""
    classes = classes_of(thermal_config(data.scene))
    k = len(classes)
    by: dict[str, dict[str, Any]] = {}
    total = np.zeros((k + 1, k + 1), dtype=np.int64)
    for d, (index, pred) in preds.items():
        sel = rows[index]
        if not sel.any():
            continue
        m = thermal_metrics(pred[sel], data.truth["label"][index[sel]], classes)
        total += m.pop("confusion")
        by[d] = m
    right = np.trace(total[:k, :k])
    n_contact = total[:k].sum()
    result: dict[str, Any] = {
        "accuracy": float(right / n_contact) if n_contact else float("nan"),
        "accuracy_by_duration": {d: m["accuracy"] for d, m in by.items()},
        "family_accuracy_by_duration": {d: m["family_accuracy"] for d, m in by.items()},
        "contact_accuracy_by_duration": {d: m["contact_accuracy"] for d, m in by.items()},
        "n_contact_by_duration": {d: m["n_contact"] for d, m in by.items()},
        "confusion_pairs": confusion_pairs(total, classes),
    }
    if "1.0" in by:
        result["per_material_accuracy"] = by["1.0"]["per_material_accuracy"]
    return result


def oracle_accuracy_by_duration(data: EvalData, limit: int | None = None) -> dict[str, Any]:
    """``oracle_accuracy_by_duration`` (and the oracle's family accuracy) on ``data``: the physics
    fit given each pixel's true heat capacity, loss and heater (``latent_heat_capacity_j_m2k``,
    ``latent_loss_w_m2k``, ``latent_heater_w_m2``), the material and every nuisance unknown (their
    ranges known from the scene). ``limit``: first rows only."""
    from tactile_learn.estimators.classical.physics_fit import PhysicsFitEstimator

    for key in ("latent_heat_capacity_j_m2k", "latent_loss_w_m2k", "latent_heater_w_m2"):
        if key not in data.extra:
            raise DataError(f"{data.source}: the oracle needs {key} (generate with the 'latent' output)")
    if limit is not None:
        data = data.subset(slice(0, limit))
    out: dict[str, Any] = {"oracle_accuracy_by_duration": {}, "oracle_family_accuracy_by_duration": {}}
    materials = thermal_config(data.scene).material_list
    for d in DURATIONS_S:
        x, valid = view(data, d)
        if not valid.any():
            continue
        oracle = PhysicsFitEstimator(
            data.scene,
            heat_capacity=data.extra["latent_heat_capacity_j_m2k"][valid],
            loss=data.extra["latent_loss_w_m2k"][valid],
            heater=data.extra["latent_heater_w_m2"][valid],
        ).prepare()
        m = thermal_metrics(oracle.predict_proba(x[valid]), data.truth["label"][valid], materials)
        out["oracle_accuracy_by_duration"][duration_key(d)] = m["accuracy"]
        out["oracle_family_accuracy_by_duration"][duration_key(d)] = m["family_accuracy"]
    return out
