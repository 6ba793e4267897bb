"""The contact-shape library: indenters and the surface pressure they press into a soft layer.

Kinds (all forces in N, lengths in mm, pressures in kPa):

- ``sphere``: rigid sphere of radius ``radius_mm``, Hertz: ``a = (3 F R / (4 E*))^(1/3)``,
  ``p(r) = p0 sqrt(1 - r^2/a^2)``, ``p0 = 3 F / (2 pi a^2)``;
- ``punch``: rigid flat round punch of radius ``radius_mm`` (Boussinesq):
  ``p(r) = F / (2 pi a sqrt(a^2 - r^2))``; the edge singularity is clamped at ``r = 0.999 a`` (its
  integrable tail is restored by the force normalisation below); ``tilt`` in [-1, 1] adds a moment
  ``M`` about the axis across ``angle_deg`` (a coin pushed off its centre), still in full contact:
  ``p = F (1 + tilt * s / a) / (2 pi a sqrt(a^2 - r^2))`` with ``tilt = 3 M / (F a)`` (``s`` along
  ``angle_deg`` from the centre); at ``|tilt| = 1`` the far rim is about to lift;
- ``block``: flat rectangular block ``width_mm x length_mm`` rotated by ``angle_deg`` (its length
  along that angle), pressure ``F / (w l)`` (a compliant pad; a rigid block's edge peaks are not
  modelled); ``tilt`` in [-1, 1] makes it a *tilted block*, pressed a little askew: the pressure
  varies linearly along the length, ``p ~ 1 + tilt * s / (l / 2)`` (``s`` from the centre), zero at
  one end when ``|tilt| = 1``;
- ``edge``: rounded line edge (cylinder of tip radius ``radius_mm``, length ``length_mm``, at
  ``angle_deg``), 2-D Hertz across the line: ``b = sqrt(4 F' R / (pi E*))``,
  ``p = (2 F' / (pi b)) sqrt(1 - d^2/b^2)`` with ``F' = F / length``;
- ``ring``: a flat washer, outer radius ``radius_mm``, hole ``hole_fraction * radius_mm``, uniform
  pressure on the annulus (compliant, like ``block``);
- ``terminal``: a ring terminal (the seed's "electrical connector lug"), a compound shape: a ring as
  above plus a tongue ``width_mm`` wide reaching ``length_mm`` beyond the ring's rim at
  ``angle_deg``, uniform pressure on the union;
- ``blob``: a smooth random field, band-limited: the sum of :data:`BLOB_BUMPS` truncated Gaussian
  bumps of width ``width_mm`` (the field's correlation length: no detail finer than that) centred
  at random within ``radius_mm`` of the contact's centre, with random heights (``detail``).

Each contact is rasterised into its own window of the fine lattice (cell centres at
``(k + 0.5) h``), averaged over ``ss x ss`` sub-samples per cell for the kinds with sharp outlines,
and scaled so that the window carries exactly the contact's force: the lattice never gains or
loses load, whatever the contact's size. A contact smaller than the lattice falls back to a point
load shared bilinearly by its four nearest cells.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np

__all__ = [
    "BLOB_BUMPS",
    "DETAIL",
    "KINDS",
    "ContactBatch",
    "Windows",
    "contact_radius_mm",
    "rasterize",
    "window_cells",
    "window_size",
]

#: codes are indices into this tuple (``latent_kind``): new kinds are appended, never inserted
KINDS: tuple[str, ...] = ("sphere", "punch", "block", "edge", "ring", "terminal", "blob")
#: sub-samples per lattice cell and axis: sharp-edged kinds need the cell's covered fraction
SUBSAMPLES = {"sphere": 1, "punch": 1, "block": 3, "edge": 3, "ring": 3, "terminal": 3, "blob": 1}
#: Gaussian bumps of a ``blob``; each takes three uniform numbers of ``detail`` (angle, radius, height)
BLOB_BUMPS = 4
#: uniform numbers per contact that shape a ``blob`` (other kinds ignore them)
DETAIL = 3 * BLOB_BUMPS
#: a blob's bumps are cut off this many widths from their centre (1.1 % of the peak: compact support)
BLOB_CUTOFF = 3.0


@dataclass(frozen=True)
class ContactBatch:
    """Contacts of one kind, flat over (frame, slot): every array has shape ``(n,)`` (``detail``:
    ``(n, DETAIL)``). ``hole_fraction``, ``tilt`` and ``detail`` default to zeros."""

    x_mm: np.ndarray
    y_mm: np.ndarray
    force_n: np.ndarray
    radius_mm: np.ndarray
    width_mm: np.ndarray
    length_mm: np.ndarray
    angle_deg: np.ndarray
    hole_fraction: np.ndarray | None = None
    tilt: np.ndarray | None = None
    detail: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.x_mm)

    def holes(self) -> np.ndarray:
        return np.zeros(len(self)) if self.hole_fraction is None else np.asarray(self.hole_fraction, np.float64)

    def tilts(self) -> np.ndarray:
        return np.zeros(len(self)) if self.tilt is None else np.asarray(self.tilt, np.float64)

    def details(self) -> np.ndarray:
        return np.zeros((len(self), DETAIL)) if self.detail is None else np.asarray(self.detail, np.float64)


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
    elif kind in ("punch", "ring"):
        extent = 2 * radius_mm
    elif kind == "block":
        extent = float(np.hypot(width_mm, length_mm))
    elif kind == "edge":
        half = float(
            edge_half_width_mm(np.float64(force_n), np.float64(radius_mm), np.float64(min_length_mm), e_star_mpa)
        )
        extent = float(np.hypot(length_mm, 2 * half))
    elif kind == "terminal":
        # the tongue may point any way from the ring's centre; its corners reach past R + length
        extent = 2 * float(np.hypot(radius_mm + length_mm, width_mm / 2))
    elif kind == "blob":
        extent = 2 * (radius_mm + BLOB_CUTOFF * width_mm)
    else:
        raise ValueError(f"unknown stimulus kind {kind!r}")
    # +3: the window starts at the centre's cell minus size//2, so one cell of slack per side and one
    # for the bilinear point-load fallback
    return int(np.ceil(extent / h)) + 3


def window_cells(kind: str, c: ContactBatch, h: float, e_star_mpa: float) -> np.ndarray:
    """Per contact, the cells per side of a window that holds it (:func:`window_size` with the
    contact's own parameters instead of the maxima)."""
    if kind == "sphere":
        extent = 2 * contact_radius_mm(c.force_n, c.radius_mm, e_star_mpa)
    elif kind in ("punch", "ring"):
        extent = 2 * np.asarray(c.radius_mm, np.float64)
    elif kind == "block":
        extent = np.hypot(c.width_mm, c.length_mm)
    elif kind == "edge":
        half = edge_half_width_mm(c.force_n, c.radius_mm, np.maximum(c.length_mm, 1e-12), e_star_mpa)
        extent = np.hypot(c.length_mm, 2 * half)
    elif kind == "terminal":
        extent = 2 * np.hypot(c.radius_mm + c.length_mm, np.asarray(c.width_mm) / 2)
    elif kind == "blob":
        extent = 2 * (c.radius_mm + BLOB_CUTOFF * np.asarray(c.width_mm))
    else:
        raise ValueError(f"unknown stimulus kind {kind!r}")
    return np.ceil(np.asarray(extent, np.float64) / h).astype(np.int64) + 3


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
        tilts = c.tilts()
        if not tilts.any():  # untilted punches: the arithmetic they always had
            return np.where(inside, 1.0 / np.sqrt(gap), 0.0)
        theta = np.deg2rad(c.angle_deg)[col]
        # |tilt| <= 1 (validated) keeps the profile non-negative inside the disc; the clip guards rounding
        moment = np.maximum(1.0 + tilts[col] * (dx * np.cos(theta) + dy * np.sin(theta)) / a, 0.0)
        return np.where(inside, moment / np.sqrt(gap), 0.0)
    if kind == "blob":
        return _blob(dx, dy, c)
    if kind == "ring":
        return _annulus(dx, dy, c).astype(np.float64)
    theta = np.deg2rad(c.angle_deg)[col]
    along = dx * np.cos(theta) + dy * np.sin(theta)
    across = -dx * np.sin(theta) + dy * np.cos(theta)
    if kind == "block":
        half_length = c.length_mm[col] / 2
        inside = (np.abs(along) <= half_length) & (np.abs(across) <= c.width_mm[col] / 2)
        # |tilt| <= 1 (validated) keeps the linear profile non-negative; the clip guards rounding
        profile = np.maximum(1.0 + c.tilts()[col] * along / half_length, 0.0)
        return np.where(inside, profile, 0.0)
    if kind == "edge":
        b = np.maximum(edge_half_width_mm(c.force_n, c.radius_mm, c.length_mm, e_star_mpa), _MIN_WIDTH_MM)[col]
        profile = np.sqrt(np.maximum(1.0 - (across / b) ** 2, 0.0))
        return np.where(np.abs(along) <= c.length_mm[col] / 2, profile, 0.0)
    if kind == "terminal":
        outer = c.radius_mm[col]
        outside_hole = dx * dx + dy * dy >= (c.holes()[col] * outer) ** 2
        tongue = (along >= 0) & (along <= outer + c.length_mm[col]) & (np.abs(across) <= c.width_mm[col] / 2)
        return (_annulus(dx, dy, c) | (tongue & outside_hole)).astype(np.float64)
    raise ValueError(f"unknown stimulus kind {kind!r}")


def _annulus(dx: np.ndarray, dy: np.ndarray, c: ContactBatch) -> np.ndarray:
    """Inside the ring of outer radius ``radius_mm`` and hole ``hole_fraction * radius_mm``."""
    col = (slice(None), None, None)
    r2 = dx * dx + dy * dy
    outer = c.radius_mm[col]
    return (r2 <= outer * outer) & (r2 >= (c.holes()[col] * outer) ** 2)


def _blob(dx: np.ndarray, dy: np.ndarray, c: ContactBatch) -> np.ndarray:
    """Sum of truncated Gaussian bumps (see the module docstring); ``detail`` places and scales them."""
    col = (slice(None), None, None)
    detail = c.details()
    sigma = np.maximum(c.width_mm, _MIN_WIDTH_MM)[col]
    floor = np.exp(-0.5 * BLOB_CUTOFF**2)  # subtracted so that each bump ends at zero, continuously
    total = np.zeros(np.broadcast_shapes(dx.shape, dy.shape))
    for b in range(BLOB_BUMPS):
        angle = 2 * np.pi * detail[:, 3 * b]
        # sqrt: centres uniform over the disc of radius_mm, not crowded at its middle
        reach = c.radius_mm * np.sqrt(detail[:, 3 * b + 1])
        height = 0.25 + 0.75 * detail[:, 3 * b + 2]
        cx, cy = (reach * np.cos(angle))[col], (reach * np.sin(angle))[col]
        bump = np.exp(-((dx - cx) ** 2 + (dy - cy) ** 2) / (2 * sigma * sigma)) - floor
        total += height[col] * np.maximum(bump, 0.0)
    return total


#: sub-samples one call to :func:`_rasterize` evaluates at most (unless one window alone holds more):
#: the shape's float64 temporaries stay near 0.3 GB each instead of growing with the batch (3,600 long
#: edges of 58 mm took 9.7 GB in one piece); each contact is computed alone, so splitting changes no bit
RASTER_SAMPLES_PER_CALL = 1 << 25


def rasterize(kind: str, contacts: ContactBatch, h: float, size: int, e_star_mpa: float) -> Windows:
    """Rasterise ``contacts`` of one ``kind`` into ``size x size`` windows of the lattice of pitch ``h``
    (in slices of at most :data:`RASTER_SAMPLES_PER_CALL` sub-samples)."""
    n = len(contacts)
    per_contact = (size * SUBSAMPLES[kind]) ** 2
    step = max(1, RASTER_SAMPLES_PER_CALL // per_contact)
    if n <= step:
        return _rasterize(kind, contacts, h, size, e_star_mpa)
    parts = [_rasterize(kind, _slice(contacts, slice(i, i + step)), h, size, e_star_mpa) for i in range(0, n, step)]
    return Windows(
        y0=np.concatenate([w.y0 for w in parts]),
        x0=np.concatenate([w.x0 for w in parts]),
        values=np.concatenate([w.values for w in parts]),
    )


def _slice(contacts: ContactBatch, part: slice) -> ContactBatch:
    # the optional arrays (hole_fraction, tilt, detail) stay None where they were
    sliced: dict[str, Any] = {}
    for f in fields(contacts):
        value = getattr(contacts, f.name)
        sliced[f.name] = None if value is None else value[part]
    return ContactBatch(**sliced)


def _rasterize(kind: str, contacts: ContactBatch, h: float, size: int, e_star_mpa: float) -> Windows:
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
