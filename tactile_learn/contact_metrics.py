"""Metrics of contact images (the capacitive task): predicted ``(B, 2, H, W)`` force image (N per
fine pixel) and contact mask (probability; in contact at >= 0.5) against the true ones.

Per frame with contact (true mask non-empty):

- ``iou``: intersection over union of the predicted and true masks;
- ``centroid_err_mm``: distance between the force-weighted centroids inside the predicted and the
  true mask (contacts as a whole; the true centroid from the true surface force);
- ``orientation_err_deg``: between the principal axes of the masks' second moments, in [0, 90],
  only where the true mask is elongated (``elongation >= 1.5``, area >= 4 pixels: a round contact
  has no orientation);
- ``area_err``: predicted over true mask area, minus 1;
- ``force_err``: total predicted force over true force, minus 1.

Groups: ``by_kind`` (frames with exactly one contact, by its shape kind); separation
(``separation_rate``, CapContact's metric): over frames with two contacts whose true masks are
two components, the share where the predicted mask has exactly two components, each overlapping a
different true one; ``separation_by_gap`` bins it by the gap between the true contacts (mm).
``false_contact_rate``: frames without contact where the prediction shows one.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
from scipy import ndimage

from synth.stimuli import KINDS
from tactile_learn.estimators.classical.contact_shapes import label_contacts, moments

__all__ = ["ELONGATED", "GAP_BINS_MM", "contact_metrics", "frame_metrics", "separation"]

#: the true mask's elongation from which orientation is scored
ELONGATED = 1.5
#: gap bins (mm) between two true contacts for ``separation_by_gap``
GAP_BINS_MM: tuple[float, ...] = (0.0, 0.5, 1.0, 2.0, 4.0)


def frame_metrics(pred: np.ndarray, force: np.ndarray, mask: np.ndarray, h_mm: float) -> dict[str, np.ndarray]:
    """Per-frame metrics (NaN where undefined) of predictions ``(B, 2, H, W)`` against the true
    force ``(B, H, W)`` and mask ``(B, H, W)``."""
    b = len(pred)
    p_mask = pred[:, 1] >= 0.5
    p_force = np.maximum(pred[:, 0].astype(np.float64), 0.0)
    t_mask = mask.astype(bool)
    t_force = force.astype(np.float64)
    inter = (p_mask & t_mask).sum(axis=(1, 2))
    union = (p_mask | t_mask).sum(axis=(1, 2))
    t_area = t_mask.sum(axis=(1, 2))
    has = t_area > 0
    out = {
        "iou": np.where(has, inter / np.maximum(union, 1), np.nan),
        "area_err": np.where(has, p_mask.sum(axis=(1, 2)) / np.maximum(t_area, 1) - 1.0, np.nan),
        "force_err": np.where(has, p_force.sum(axis=(1, 2)) / np.maximum(t_force.sum(axis=(1, 2)), 1e-12) - 1, np.nan),
        "centroid_err_mm": np.full(b, np.nan),
        "orientation_err_deg": np.full(b, np.nan),
    }
    for i in np.flatnonzero(has):
        tx, ty, t_angle, t_elong = moments(np.where(t_mask[i], t_force[i], 0.0), h_mm)
        _, _, t_angle, t_elong = moments(t_mask[i].astype(float), h_mm)
        if not p_mask[i].any():
            continue  # a missed contact: IoU 0, no centroid or orientation
        weights = np.where(p_mask[i], p_force[i], 0.0)
        px, py, _, _ = moments(weights if weights.sum() > 0 else p_mask[i].astype(float), h_mm)
        out["centroid_err_mm"][i] = np.hypot(px - tx, py - ty)
        if t_elong >= ELONGATED and t_area[i] >= 4:
            _, _, p_angle, _ = moments(p_mask[i].astype(float), h_mm)
            diff = abs(p_angle - t_angle) % 180.0
            out["orientation_err_deg"][i] = min(diff, 180.0 - diff) if np.isfinite(diff) else 90.0
    return out


def separation(pred: np.ndarray, mask: np.ndarray, h_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every frame: whether its true mask has exactly two contacts (``eligible``), the gap
    between them (mm, closest pixel centres less one pixel), and whether the prediction separates
    them (two predicted components, each overlapping a different true one)."""
    t_labels, t_count = label_contacts(mask.astype(bool))
    p_labels, p_count = label_contacts(pred[:, 1] >= 0.5)
    eligible = t_count == 2
    gap = np.full(len(pred), np.nan)
    separated = np.zeros(len(pred), dtype=bool)
    for i in np.flatnonzero(eligible):
        a, b = t_labels[i] == 1, t_labels[i] == 2
        # distance from every pixel to the nearest pixel of contact a, read at contact b's pixels
        dist = ndimage.distance_transform_edt(~a)
        gap[i] = (float(dist[b].min()) - 1.0) * h_mm
        if p_count[i] != 2:
            continue
        overlap = np.array(
            [[np.any((p_labels[i] == p) & (t_labels[i] == t)) for t in (1, 2)] for p in (1, 2)], dtype=bool
        )
        # one-to-one: each predicted contact overlaps exactly one true contact, a different one each
        # (a blob over both plus a sliver beside one is not a separation)
        separated[i] = bool(overlap.sum(axis=1).tolist() == [1, 1] and overlap.sum(axis=0).tolist() == [1, 1])
    return eligible, gap, separated


def _summary(values: np.ndarray) -> dict[str, float]:
    v = values[np.isfinite(values)]
    if not len(v):
        return {"mean": float("nan"), "median": float("nan"), "p95": float("nan"), "n": 0}
    return {"mean": float(v.mean()), "median": float(np.median(v)), "p95": float(np.percentile(v, 95)), "n": len(v)}


def contact_metrics(
    pred: np.ndarray,
    force: np.ndarray,
    mask: np.ndarray,
    h_mm: float,
    kind: np.ndarray | None = None,
    n_contacts: np.ndarray | None = None,
) -> dict[str, Any]:
    """All contact metrics; ``kind`` (B, K) kind indices into ``synth.stimuli.KINDS`` of the
    contacts touching in each frame (-1: none) and ``n_contacts`` (B,) give the groups."""
    pred = np.asarray(pred)
    if pred.ndim != 4 or pred.shape[1] != 2 or pred.shape[2:] != mask.shape[1:] or len(pred) != len(mask):
        raise ValueError(f"prediction shape {pred.shape} does not match the truth's {mask.shape} (B, 2, H, W)")
    per = frame_metrics(pred, force, mask, h_mm)
    has = np.isfinite(per["iou"])
    out: dict[str, Any] = {
        "iou_mean": float(np.nanmean(per["iou"])) if has.any() else float("nan"),
        "iou_median": float(np.nanmedian(per["iou"])) if has.any() else float("nan"),
        "centroid_err_mm_median": _summary(per["centroid_err_mm"])["median"],
        "centroid_err_mm_p95": _summary(per["centroid_err_mm"])["p95"],
        "orientation_err_deg_median": _summary(per["orientation_err_deg"])["median"],
        "area_err_median": _summary(np.abs(per["area_err"]))["median"],
        "force_err_median": _summary(np.abs(per["force_err"]))["median"],
        "missed_rate": float(np.mean((pred[has, 1] < 0.5).all(axis=(1, 2)))) if has.any() else float("nan"),
        "n_frames_with_contact": int(has.sum()),
    }
    empty = ~has
    out["false_contact_rate"] = float(np.mean((pred[empty, 1] >= 0.5).any(axis=(1, 2)))) if empty.any() else 0.0
    if n_contacts is not None and kind is not None:
        by_kind: dict[str, Any] = {}
        single = has & (n_contacts == 1)
        first = np.max(kind, axis=1) if kind.ndim == 2 else kind  # the one present contact's kind
        for code, name in enumerate(KINDS):
            sel = single & (first == code)
            if sel.any():
                by_kind[name] = {
                    "n_frames": int(sel.sum()),
                    "iou_mean": float(np.nanmean(per["iou"][sel])),
                    "centroid_err_mm_median": _summary(per["centroid_err_mm"][sel])["median"],
                    "orientation_err_deg_median": _summary(per["orientation_err_deg"][sel])["median"],
                    "n_oriented": _summary(per["orientation_err_deg"][sel])["n"],
                    "area_err_median": _summary(np.abs(per["area_err"][sel]))["median"],
                }
        out["by_kind"] = by_kind
        eligible, gap, separated = separation(pred, mask, h_mm)
        eligible &= n_contacts == 2
        out["n_pairs"] = int(eligible.sum())
        out["separation_rate"] = float(separated[eligible].mean()) if eligible.any() else float("nan")
        bins: dict[str, Any] = {}
        edges = (*GAP_BINS_MM, np.inf)
        for lo, hi in itertools.pairwise(edges):
            sel = eligible & (gap >= lo) & (gap < hi)
            key = f"{lo:g}-{hi:g}" if np.isfinite(hi) else f">={lo:g}"
            if sel.any():
                bins[key] = {"n": int(sel.sum()), "rate": float(separated[sel].mean())}
        out["separation_by_gap_mm"] = bins
    return out
