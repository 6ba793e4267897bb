"""Indenters and the surface pressure they press into a soft layer.

Kinds (all forces in N, lengths in mm, pressures in kPa):

- ``sphere``: rigid sphere of radius ``radius_mm``, Hertz: ``a = (3 F R / (4 E*))^(1/3)``,
  ``p(r) = p0 sqrt(1 - r^2/a^2)``, ``p0 = 3 F / (2 pi a^2)``;
- ``punch``: rigid flat round punch of radius ``radius_mm`` (Boussinesq):
  ``p(r) = F / (2 pi a sqrt(a^2 - r^2))``; the edge singularity is clamped at ``r = 0.999 a`` (its
  integrable tail is restored by the force normalisation below);
- ``block``: flat rectangular block ``width_mm x length_mm`` rotated by ``angle_deg``, uniform
  pressure ``F / (w l)`` (a compliant pad; a rigid block's edge peaks are not modelled);
- ``edge``: rounded line edge (cylinder of tip radius ``radius_mm``, length ``length_mm``, at
  ``angle_deg``), 2-D Hertz across the line: ``b = sqrt(4 F' R / (pi E*))``,
  ``p = (2 F' / (pi b)) sqrt(1 - d^2/b^2)`` with ``F' = F / length``.

Each contact is rasterised into its own window of the fine lattice (cell centres at
``(k + 0.5) h``), averaged over ``ss x ss`` sub-samples per cell for the kinds with sharp outlines,
and scaled so that the window carries exactly the contact's force: the lattice never gains or
loses load, whatever the contact's size. A contact smaller than the lattice falls back to a point
load shared bilinearly by its four nearest cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["KINDS", "ContactBatch", "Windows", "contact_radius_mm", "rasterize", "window_size"]

KINDS: tuple[str, ...] = ("sphere", "punch", "block", "edge")
#: sub-samples per lattice cell and axis: sharp-edged kinds need the cell's covered fraction
SUBSAMPLES = {"sphere": 1, "punch": 1, "block": 3, "edge": 3}


@dataclass(frozen=True)
class ContactBatch:
    """Contacts of one kind, flat over (frame, slot): every array has shape ``(n,)``."""

    x_mm: np.ndarray
    y_mm: np.ndarray
    force_n: np.ndarray
    radius_mm: np.ndarray
    width_mm: np.ndarray
    length_mm: np.ndarray
    angle_deg: np.ndarray

    def __len__(self) -> int:
        return len(self.x_mm)


@dataclass(frozen=True)
class Windows:
    """Rasterised contacts: ``values[c]`` (kPa) covers lattice rows ``y0[c] + 0..W-1`` and columns
    ``x0[c] + 0..W-1``."""

    y0: np.ndarray
    x0: np.ndarray
    values: np.ndarray


def contact_radius_mm(force_n: np.ndarray | float, radius_mm: np.ndarray | float, e_star_mpa: float) -> np.ndarray:
    """Hertz contact radius of a rigid sphere on an elastic half-space (mm)."""
    return np.cbrt(3.0 * np.asarray(force_n, dtype=np.float64) * np.asarray(radius_mm) / (4.0 * e_star_mpa))


def edge_half_width_mm(
    force_n: np.ndarray | float, radius_mm: np.ndarray | float, length_mm: np.ndarray | float, e_star_mpa: float
) -> np.ndarray:
    """2-D Hertz half-width of a cylinder edge pressed with ``force_n / length_mm`` per mm."""
    per_length = np.asarray(force_n, dtype=np.float64) / length_mm
    return np.sqrt(4.0 * per_length * radius_mm / (np.pi * e_star_mpa))


def window_size(
    kind: str,
    h: float,
    e_star_mpa: float,
    *,
    radius_mm: float,
    force_n: float,
    width_mm: float = 0.0,
    length_mm: float = 0.0,
    min_length_mm: float = 1.0,
) -> int:
    """Lattice cells per side of a window that holds any contact of ``kind`` whose parameters stay
    within the given maxima (``min_length_mm``: the shortest edge, whose Hertz strip is widest)."""
    if kind == "sphere":
        extent = 2 * float(contact_radius_mm(force_n, radius_mm, e_star_mpa))
    elif kind == "punch":
        extent = 2 * radius_mm
    elif kind == "block":
        extent = float(np.hypot(width_mm, length_mm))
    elif kind == "edge":
        half = float(
            edge_half_width_mm(np.float64(force_n), np.float64(radius_mm), np.float64(min_length_mm), e_star_mpa)
        )
        extent = float(np.hypot(length_mm, 2 * half))
    else:
        raise ValueError(f"unknown stimulus kind {kind!r}")
    # +3: the window starts at the centre's cell minus size//2, so one cell of slack per side and one
    # for the bilinear point-load fallback
    return int(np.ceil(extent / h)) + 3


#: floor of a Hertz contact width (mm), see :func:`_shape`
_MIN_WIDTH_MM = 1e-6


def _shape(kind: str, dx: np.ndarray, dy: np.ndarray, c: ContactBatch, e_star_mpa: float) -> np.ndarray:
    """Unnormalised pressure shape at offsets (dx, dy) mm from each contact's centre.

    ``dx``/``dy`` broadcast against per-contact parameters shaped ``(n, 1, 1)``.
    """
    col = (slice(None), None, None)
    # Hertz widths vanish with the force: floor them at a nanometre so that no 0/0 appears. The
    # shape of such a contact is then zero on every sub-sample (none lies within a nanometre of its
    # centre), and ``rasterize`` hands its force to the bilinear point-load fallback.
    if kind == "sphere":
        a = np.maximum(contact_radius_mm(c.force_n, c.radius_mm, e_star_mpa), _MIN_WIDTH_MM)[col]
        return np.sqrt(np.maximum(1.0 - (dx * dx + dy * dy) / (a * a), 0.0))
    if kind == "punch":
        a = c.radius_mm[col]
        r2 = dx * dx + dy * dy
        inside = r2 < a * a
        # clamp the integrable edge singularity; normalisation restores the total force
        gap = np.maximum(a * a - r2, (0.045 * a) ** 2)
        return np.where(inside, 1.0 / np.sqrt(gap), 0.0)
    theta = np.deg2rad(c.angle_deg)[col]
    along = dx * np.cos(theta) + dy * np.sin(theta)
    across = -dx * np.sin(theta) + dy * np.cos(theta)
    if kind == "block":
        inside = (np.abs(along) <= c.length_mm[col] / 2) & (np.abs(across) <= c.width_mm[col] / 2)
        return inside.astype(np.float64)
    if kind == "edge":
        b = np.maximum(edge_half_width_mm(c.force_n, c.radius_mm, c.length_mm, e_star_mpa), _MIN_WIDTH_MM)[col]
        profile = np.sqrt(np.maximum(1.0 - (across / b) ** 2, 0.0))
        return np.where(np.abs(along) <= c.length_mm[col] / 2, profile, 0.0)
    raise ValueError(f"unknown stimulus kind {kind!r}")


def rasterize(kind: str, contacts: ContactBatch, h: float, size: int, e_star_mpa: float) -> Windows:
    """Rasterise ``contacts`` of one ``kind`` into ``size x size`` windows of the lattice of pitch ``h``."""
    n = len(contacts)
    ss = SUBSAMPLES[kind]
    y0 = np.floor(contacts.y_mm / h).astype(np.int64) - size // 2
    x0 = np.floor(contacts.x_mm / h).astype(np.int64) - size // 2
    sub = (np.arange(ss) + 0.5) / ss  # sub-sample positions inside a cell, in cells
    cells = np.arange(size)
    # lattice coordinates (mm) of every sub-sample, relative to each contact's centre: (n, size*ss)
    ys = ((y0[:, None, None] + cells[None, :, None] + sub[None, None, :]) * h).reshape(n, -1) - contacts.y_mm[:, None]
    xs = ((x0[:, None, None] + cells[None, :, None] + sub[None, None, :]) * h).reshape(n, -1) - contacts.x_mm[:, None]
    shape = _shape(kind, xs[:, None, :], ys[:, :, None], contacts, e_star_mpa)
    if ss > 1:
        shape = shape.reshape(n, size, ss, size, ss).mean(axis=(2, 4))
    total = shape.sum(axis=(1, 2))
    values = np.zeros((n, size, size), dtype=np.float64)
    ok = total > 0
    # force (N) over cell area (mm^2) is MPa; x1000 for kPa
    scale = np.divide(contacts.force_n * 1000.0 / (h * h), total, out=np.zeros(n), where=ok)
    values[ok] = shape[ok] * scale[ok, None, None]
    if not ok.all():
        _point_load(values, ~ok, contacts, h, y0, x0)
    return Windows(y0=y0, x0=x0, values=values)


def _point_load(
    values: np.ndarray, which: np.ndarray, c: ContactBatch, h: float, y0: np.ndarray, x0: np.ndarray
) -> None:
    """Share each selected contact's force bilinearly among its four nearest cell centres."""
    idx = np.flatnonzero(which)
    fy = c.y_mm[idx] / h - 0.5 - y0[idx]  # position in window cells, relative to cell centres
    fx = c.x_mm[idx] / h - 0.5 - x0[idx]
    iy, ix = np.floor(fy).astype(np.int64), np.floor(fx).astype(np.int64)
    ty, tx = fy - iy, fx - ix
    pressure = c.force_n[idx] * 1000.0 / (h * h)
    for oy, wy in ((0, 1 - ty), (1, ty)):
        for ox, wx in ((0, 1 - tx), (1, tx)):
            values[idx, iy + oy, ix + ox] += pressure * wy * wx
