"""The cover's spreading: surface pressure on the fine lattice -> load on every tab.

The tabs are the only load path through the air-gapped dielectric, so the load on tab ``(i, j)``
is the vertical stress under the cover integrated over that cell's ``pitch x pitch`` square: a
linear map of the surface pressure. The stress comes from Boussinesq's exact rectangle kernel
(``synth.mechanics.rectangle_stress``: a half-space, depth = the cover's thickness) for each
piecewise-constant lattice cell, integrated over the tab's square by the midpoint rule on ``q x q``
points per lattice cell (``q`` odd, so the points fall on a lattice of pitch ``h / q``).

The map is translation invariant: the load depends only on the offset between a lattice cell and
the tab, so one table ``S[dy, dx]`` (box sums of the point stresses over a tab's square, by
cumulative sums) serves every tab. A uniform pressure over the whole plane would put exactly
``p pitch^2`` on every tab; pressure beyond the lattice's pad is not modelled (at 2 mm from the
array under a 0.5 mm cover its stress is below 0.1 % of its value straight below).
"""

from __future__ import annotations

import numpy as np

from synth.mechanics import rectangle_stress
from synth.sensors.capacitive.config import ArrayGeometry

__all__ = ["tab_load_operator"]

#: kPa x mm^2 -> N
KPA_MM2_TO_N = 1e-3


def tab_load_operator(geometry: ArrayGeometry, depth_mm: float, quadrature: int = 3) -> np.ndarray:
    """``(N M, Hp Wp)`` float64: load (N) on every tab (row-major) per kPa on every cell of the padded
    lattice (row-major, ``geometry.lattice_shape``)."""
    if quadrature < 1 or quadrature % 2 == 0:
        raise ValueError("quadrature must be a positive odd number")
    s, h, pad, q = geometry.samples_per_pitch, geometry.h_mm, geometry.pad_cells, quadrature
    n_rows, n_cols = geometry.n_rows, geometry.n_cols
    hp, wp = geometry.lattice_shape
    span = s * q  # quadrature points per tab side
    # delta = (source cell's array coordinate) - (tab's first fine row), in fine cells; the offset of
    # quadrature point a from the source's centre is (a + 0.5)/q - 0.5 - delta = (a - q delta - (q-1)/2) / q
    d_lo = -pad - (max(n_rows, n_cols) - 1) * s
    d_hi = max(hp, wp) - pad - 1
    j_lo = -q * d_hi - (q - 1) // 2
    j_hi = span - 1 - q * d_lo - (q - 1) // 2
    offsets = np.arange(j_lo, j_hi + 1) * (h / q)  # mm, on the quadrature lattice
    oy, ox = np.meshgrid(offsets, offsets, indexing="ij")
    point = rectangle_stress(-ox - h / 2, -ox + h / 2, -oy - h / 2, -oy + h / 2, depth_mm)
    # box sums of span x span quadrature points via a summed-area table
    table = np.zeros((len(offsets) + 1, len(offsets) + 1))
    table[1:, 1:] = point.cumsum(axis=0).cumsum(axis=1)
    deltas = np.arange(d_lo, d_hi + 1)
    start = -q * deltas - (q - 1) // 2 - j_lo  # index of each delta's first point in ``offsets``
    stop = start + span
    box = (
        table[stop[:, None], stop[None, :]]
        - table[start[:, None], stop[None, :]]
        - table[stop[:, None], start[None, :]]
        + table[start[:, None], start[None, :]]
    )
    per_kpa = box * (h / q) ** 2 * KPA_MM2_TO_N  # S[delta_y, delta_x]
    rows = np.arange(hp) - pad  # array coordinate of each lattice row
    cols = np.arange(wp) - pad
    dy = rows[None, :] - (np.arange(n_rows) * s)[:, None] - d_lo  # (N, Hp) index into S
    dx = cols[None, :] - (np.arange(n_cols) * s)[:, None] - d_lo  # (M, Wp)
    op = per_kpa[dy[:, None, :, None], dx[None, :, None, :]]  # (N, M, Hp, Wp)
    return np.ascontiguousarray(op.reshape(n_rows * n_cols, hp * wp))
