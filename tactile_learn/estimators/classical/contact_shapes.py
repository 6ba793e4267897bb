"""Contact shapes from a force image and a contact mask: threshold, connected components and image
moments (outline, area, centroid, orientation). numpy/scipy only; shared by the estimators, the
metrics and the fingertip pipeline.

A contact is a connected component of the mask (8-connected: two blobs that touch at a corner
are one contact). On a lattice of pitch ``h`` (mm), pixel ``(k, l)`` is centred at
``x = (l + 0.5) h``, ``y = (k + 0.5) h``:

- ``area_mm2``: pixels x ``h^2``;
- ``centroid_mm``: the force-weighted mean position (the mask's own centre where it carries no force);
- ``orientation_deg``: the principal axis of the mask's second central moments,
  ``0.5 atan2(2 mu11, mu20 - mu02)``, measured from +x towards +y, in [0, 180);
- ``elongation``: ``sqrt(lambda_max / lambda_min)`` of those moments (1: round; orientation is
  meaningful only well above 1);
- ``outline``: the component's boundary pixels (in the mask, with a 4-neighbour outside it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

__all__ = ["ContactShape", "contact_shapes", "label_contacts", "moments", "threshold_mask"]

#: 8-connectivity
_EIGHT = np.ones((3, 3), dtype=bool)


@dataclass(frozen=True)
class ContactShape:
    area_mm2: float
    centroid_mm: tuple[float, float]
    orientation_deg: float
    elongation: float
    force_n: float
    outline: np.ndarray  # (k, 2) row, col of the boundary pixels


def threshold_mask(force: np.ndarray, fraction: float, floor: float, reach: int = 0) -> np.ndarray:
    """Contact mask of force images ``(B, H, W)``: ``force >= max(fraction x peak, floor)``, the peak
    the frame's maximum, or with ``reach > 0`` the largest value within ``reach`` pixels (each contact
    is measured against its own peak: a light contact beside a heavy one keeps its outline)."""
    if reach > 0:
        peak = ndimage.maximum_filter(force, size=(1, 2 * reach + 1, 2 * reach + 1), mode="nearest")
    else:
        peak = np.broadcast_to(force.reshape(len(force), -1).max(axis=1, initial=0.0)[:, None, None], force.shape)
    return np.asarray(force >= np.maximum(fraction * peak, floor))


def label_contacts(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Labels ``(B, H, W)`` (0 background, 1..n per frame) and the contact count per frame."""
    labels = np.zeros(mask.shape, dtype=np.int32)
    counts = np.zeros(len(mask), dtype=np.int64)
    for b in range(len(mask)):
        labels[b], counts[b] = ndimage.label(mask[b], structure=_EIGHT)
    return labels, counts


def moments(weights: np.ndarray, h_mm: float) -> tuple[float, float, float, float]:
    """Centre (x, y) in mm, orientation (deg, [0, 180)) and elongation of non-negative ``weights``
    (H, W); NaN orientation for an empty or single-pixel image."""
    total = float(weights.sum())
    if total <= 0:
        return float("nan"), float("nan"), float("nan"), float("nan")
    rows, cols = np.indices(weights.shape)
    x = (cols + 0.5) * h_mm
    y = (rows + 0.5) * h_mm
    cx, cy = float((weights * x).sum() / total), float((weights * y).sum() / total)
    mu20 = float((weights * (x - cx) ** 2).sum() / total)
    mu02 = float((weights * (y - cy) ** 2).sum() / total)
    mu11 = float((weights * (x - cx) * (y - cy)).sum() / total)
    spread = np.hypot(mu20 - mu02, 2 * mu11)
    big, small = (mu20 + mu02 + spread) / 2, (mu20 + mu02 - spread) / 2
    if big <= 0:
        return cx, cy, float("nan"), float("nan")
    # a single line of pixels has no width: its elongation is unbounded (a pixel's own extent h^2/12
    # keeps it finite and the ratio meaningful)
    pixel = h_mm**2 / 12
    angle = float(np.degrees(0.5 * np.arctan2(2 * mu11, mu20 - mu02)) % 180.0)
    return cx, cy, angle, float(np.sqrt((big + pixel) / (small + pixel)))


def contact_shapes(force: np.ndarray, mask: np.ndarray, h_mm: float) -> list[ContactShape]:
    """Every contact of one frame (``force`` and ``mask`` (H, W)), largest first."""
    labels, count = ndimage.label(mask, structure=_EIGHT)
    shapes = []
    inner = ndimage.binary_erosion(mask, border_value=0)
    for k in range(1, count + 1):
        region = labels == k
        load = np.where(region, np.maximum(force, 0.0), 0.0)
        cx, cy, _, _ = moments(load if load.sum() > 0 else region.astype(float), h_mm)
        _, _, angle, elongation = moments(region.astype(float), h_mm)
        shapes.append(
            ContactShape(
                area_mm2=float(region.sum()) * h_mm**2,
                centroid_mm=(cx, cy),
                orientation_deg=angle,
                elongation=elongation,
                force_n=float(load.sum()),
                outline=np.argwhere(region & ~inner),
            )
        )
    shapes.sort(key=lambda s: -s.area_mm2)
    return shapes
