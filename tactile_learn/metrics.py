"""Metrics, with the names used everywhere (eval JSON, bench, model cards).

Strip maps (``(B, N, M)`` pressure, estimated vs true):

- ``pearson_r_mean`` / ``pearson_r_median``: Pearson r between the estimated and true map of each
  frame, over frames whose true map is not constant (a frame without contact has no correlation);
  an estimate that is constant where the truth is not scores 0.
- ``nrmse``: RMS error over all cells of all frames divided by the RMS of the true maps (0 is
  perfect, 1 is what an all-zero estimate scores); scale-sensitive where r is not.
- ``peak_err_mm_median`` / ``peak_err_mm_mean``: for every peak of a true map (a 3 x 3 local
  maximum above 25 % of the frame's maximum, located to sub-cell precision by its 3 x 3
  centroid), the distance to the nearest peak of the estimate, in mm.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import ndimage

__all__ = ["find_peaks", "pearson_per_frame", "strip_map_metrics"]

PEAK_FRACTION = 0.25


def pearson_per_frame(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """Pearson r of each frame (float64); NaN where the true map is constant."""
    p = pred.reshape(len(pred), -1).astype(np.float64)
    t = true.reshape(len(true), -1).astype(np.float64)
    p = p - p.mean(axis=1, keepdims=True)
    t = t - t.mean(axis=1, keepdims=True)
    sp = np.sqrt((p * p).sum(axis=1))
    st = np.sqrt((t * t).sum(axis=1))
    cov = (p * t).sum(axis=1)
    # a constant truth has no correlation (NaN, excluded); a constant estimate of a varying truth: 0
    r = np.divide(cov, sp * st, out=np.zeros(len(p)), where=(sp > 0) & (st > 0))
    r[st <= 1e-12 * (1 + np.abs(true.reshape(len(true), -1)).max(axis=1))] = np.nan
    return np.clip(r, -1.0, 1.0)


def find_peaks(maps: np.ndarray, fraction: float = PEAK_FRACTION) -> list[np.ndarray]:
    """Sub-cell peak positions ``(k, 2)`` (row, col in cells) of every map in ``maps`` (B, N, M)."""
    maps = np.asarray(maps, dtype=np.float64)
    local_max = ndimage.maximum_filter(maps, size=(1, 3, 3), mode="constant", cval=-np.inf)
    top = maps.reshape(len(maps), -1).max(axis=1) if maps.size else np.zeros(len(maps))
    mask = (maps == local_max) & (maps > fraction * top[:, None, None]) & (top[:, None, None] > 0)
    padded = np.pad(maps, ((0, 0), (1, 1), (1, 1)))
    out: list[np.ndarray] = []
    offsets = np.array([-1.0, 0.0, 1.0])
    for b in range(len(maps)):
        rows, cols = np.nonzero(mask[b])
        peaks = np.empty((len(rows), 2))
        for k, (i, j) in enumerate(zip(rows, cols, strict=True)):
            patch = np.maximum(padded[b, i : i + 3, j : j + 3], 0.0)
            w = patch.sum()  # > 0: the centre is a positive maximum
            peaks[k] = (i + (patch.sum(axis=1) @ offsets) / w, j + (patch.sum(axis=0) @ offsets) / w)
        out.append(peaks)
    return out


def strip_map_metrics(pred: np.ndarray, true: np.ndarray, pitch_mm: float) -> dict[str, Any]:
    """All strip-map metrics for predicted and true maps (B, N, M)."""
    pred = np.asarray(pred, dtype=np.float64)
    true = np.asarray(true, dtype=np.float64)
    if pred.shape != true.shape:
        raise ValueError(f"prediction shape {pred.shape} differs from truth {true.shape}")
    r = pearson_per_frame(pred, true)
    valid = np.isfinite(r)
    denom = np.sqrt(np.mean(true**2)) if true.size else 0.0
    rmse = np.sqrt(np.mean((pred - true) ** 2)) if true.size else 0.0
    errors: list[float] = []
    true_peaks = find_peaks(true)
    for t_peaks, p_peaks in zip(true_peaks, find_peaks(pred), strict=True):
        if len(t_peaks) == 0 or len(p_peaks) == 0:
            continue  # no contact, or a missed one (counted in peak_miss_rate)
        d = np.sqrt(((t_peaks[:, None, :] - p_peaks[None, :, :]) ** 2).sum(axis=-1)).min(axis=1)
        errors.extend((d * pitch_mm).tolist())
    n_true_peaks = sum(len(p) for p in true_peaks)
    return {
        "pearson_r_mean": float(np.mean(r[valid])) if valid.any() else float("nan"),
        "pearson_r_median": float(np.median(r[valid])) if valid.any() else float("nan"),
        "nrmse": float(rmse / denom) if denom > 0 else float("nan"),
        "peak_err_mm_median": float(np.median(errors)) if errors else float("nan"),
        "peak_err_mm_mean": float(np.mean(errors)) if errors else float("nan"),
        "peak_miss_rate": float(1 - len(errors) / n_true_peaks) if n_true_peaks else 0.0,
        "n_frames_with_contact": int(valid.sum()),
    }
