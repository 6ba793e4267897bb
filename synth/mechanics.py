"""Surface pressure to vertical stress at depth, through an elastic cover (Boussinesq).

The surface pressure lives on a fine square lattice of pitch ``h`` (mm), piecewise constant on
each ``h x h`` cell. The vertical stress at depth ``z`` under a uniformly loaded rectangle has a
closed form (integral of Boussinesq's point-load solution; Newmark's corner formula), so the
kernel ``K(dy, dx)`` - stress at lattice offset (dy, dx) from one unit-pressure cell - is exact for
piecewise-constant pressure, however coarse the lattice is compared with ``z``.

For speed the 2-D kernel is factored into a short sum of separable terms by SVD,
``K(dy, dx) ~ sum_r g_r(dy) h_r(dx)``, keeping the fewest terms whose relative Frobenius error is
below ``rank_tol``. A linear functional "mean stress over a patch" of the field then becomes
``sum_r A_r P B_r^T``: two small matrix products per term instead of a 2-D convolution.

Model limits (documented, first order): a homogeneous, isotropic, linear-elastic half-space; the
cover's finite thickness and the strips' own stiffness are ignored (a finite layer on a rigid base
concentrates stress; the half-space spreads it slightly more than a real thin cover does).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SeparableKernel", "boussinesq_cell_kernel", "rectangle_stress", "separable_kernel"]


def _corner(a: np.ndarray, b: np.ndarray, z: float) -> np.ndarray:
    """Vertical stress at depth ``z`` under the corner of a unit-pressure rectangle [0,a] x [0,b].

    Odd in ``a`` and in ``b``, so signed extents combine by inclusion-exclusion. ``z > 0`` keeps
    ``R >= z > 0``: no division by zero.
    """
    r = np.sqrt(a * a + b * b + z * z)
    return (np.arctan(a * b / (z * r)) + a * b * z / r * (1.0 / (a * a + z * z) + 1.0 / (b * b + z * z))) / (2 * np.pi)


def rectangle_stress(x0: np.ndarray, x1: np.ndarray, y0: np.ndarray, y1: np.ndarray, z: float) -> np.ndarray:
    """Vertical stress at depth ``z`` below the origin from unit pressure on [x0,x1] x [y0,y1] (mm)."""
    if z <= 0:
        raise ValueError("depth z must be positive")
    return _corner(x1, y1, z) - _corner(x0, y1, z) - _corner(x1, y0, z) + _corner(x0, y0, z)


def boussinesq_cell_kernel(h: float, z: float, half_extent: int) -> np.ndarray:
    """Stress at depth ``z`` at lattice offsets ``-half_extent..half_extent`` (both axes) from one
    ``h x h`` cell of unit pressure, float64, shape ``(2*half_extent+1, 2*half_extent+1)``,
    indexed ``[dy, dx]``."""
    d = np.arange(-half_extent, half_extent + 1, dtype=np.float64) * h
    dy, dx = np.meshgrid(d, d, indexing="ij")
    # the observation point sits at offset (dx, dy) from the cell's centre
    return rectangle_stress(dx - h / 2, dx + h / 2, dy - h / 2, dy + h / 2, z)


@dataclass(frozen=True)
class SeparableKernel:
    """``K[dy, dx] ~ sum_r rows[r, dy] * cols[r, dx]`` on offsets ``-half..half``."""

    rows: np.ndarray  # (R, 2*half+1)
    cols: np.ndarray  # (R, 2*half+1)
    half: int
    rel_error: float

    @property
    def rank(self) -> int:
        return int(self.rows.shape[0])

    def dense(self) -> np.ndarray:
        return np.einsum("ry,rx->yx", self.rows, self.cols)


def separable_kernel(h: float, z: float, half_extent: int, rank_tol: float = 1e-4) -> SeparableKernel:
    """Low-rank factorisation of :func:`boussinesq_cell_kernel` with relative error <= ``rank_tol``."""
    kernel = boussinesq_cell_kernel(h, z, half_extent)
    u, s, vt = np.linalg.svd(kernel)
    energy = np.cumsum(s[::-1] ** 2)[::-1]  # energy[k] = sum of s_j^2 for j >= k
    total = energy[0]
    rank = len(s)
    for k in range(1, len(s)):
        if np.sqrt(energy[k] / total) <= rank_tol:
            rank = k
            break
    error = float(np.sqrt(energy[rank] / total)) if rank < len(s) else 0.0
    root = np.sqrt(s[:rank])
    return SeparableKernel(
        rows=(u[:, :rank] * root).T.copy(),
        cols=(vt[:rank] * root[:, None]).copy(),
        half=half_extent,
        rel_error=error,
    )


def patch_operator(weights: np.ndarray, profile: np.ndarray, positions: np.ndarray, half: int) -> np.ndarray:
    """``A[i, p] = sum_y weights[i, y] * profile[y - positions[p] + half]``.

    ``weights`` (n, Y) averages the stress over lattice rows ``0..Y-1`` for each of ``n`` patches;
    ``profile`` is one separable factor on offsets ``-half..half``; ``positions`` are the lattice
    rows (possibly outside ``0..Y-1``) where pressure may sit. Offsets beyond ``half`` contribute 0.
    """
    y = np.arange(weights.shape[1])
    offset = y[:, None] - positions[None, :]  # (Y, P): observation row minus load row
    inside = np.abs(offset) <= half
    table = np.where(inside, profile[np.clip(offset + half, 0, 2 * half)], 0.0)
    return weights @ table
