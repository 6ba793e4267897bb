"""The calibrated fit at batch 1: a float32 screen, then float64 where it can matter.

At batch 1 the fit is one matrix-vector product against every (contact start, template) basis:
~3.5 MB of float64 read per call, memory-bound (the batch path's matrix product is compute-bound),
~2/3 of the call. Here the product runs on a float32 copy (half the bytes), which gives every
residual sum of squares to a bound ``E`` proven below, and the float64 bases are read only for
the designs that can still be their class's best, in the classes that can still matter:

- float32 ``p = Q32^T d32`` (``d`` the centred curve, ``Q`` orthonormal columns): each component
  is off by at most ``(N + 2) u |d|`` (``u = 2^-24``: the dot product's rounding, whatever its
  summation order, ``gamma_N |q| |d|``, plus ``Q``'s and ``d``'s own rounding), so a design's
  ``|d|^2 - |p|^2`` is off by at most ``E = (2 sqrt(L) (N + 3) u + L ((N + 3) u)^2 + 4 (L + 1) u)
  |d|^2`` (``L`` columns; the last term the float32 squares and sums);
- a class is exact-scored if its screened score is within ``RELEVANT + 2 E / unit`` of the best
  (the others' probabilities are below ``exp(-RELEVANT)`` in either path); within such a class
  every design whose screened residual is within ``2 E`` of the class's screened minimum is
  recomputed in float64: the true best design is among them.

So the relevant classes' scores are the float64 path's (to its own rounding) and the others'
probabilities stay below ``exp(-RELEVANT)`` (4e-18). On the seed scene's bench frames: 6
designs recomputed per curve (median; 90 %: 38) of 1729.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

__all__ = ["OneFrameBases", "one_frame_bases", "screened_residuals"]

#: score units (log-probability) below the best beyond which a class is not exact-scored
RELEVANT = 40.0
_U32 = 2.0**-24


class OneFrameBases(NamedTuple):
    """The bases as the batch-1 screen reads them: the designs' float32 side by side (N, G L), every
    design's and the lines' float64 per design (G + 1, L, N), every design's class (G,), and the
    error bound's factor of ``|d|^2``."""

    screen: np.ndarray
    exact: np.ndarray
    design_class: np.ndarray
    error_factor: float


def one_frame_bases(q: np.ndarray, class_start: np.ndarray, n_columns: int) -> OneFrameBases:
    """The batch-1 copies of the projections ``q`` (N, (G + 1) L) (the lines last) whose class
    groups begin at ``class_start``."""
    n, width = q.shape
    n_designs = width // n_columns - 1
    exact = np.ascontiguousarray(q.reshape(n, n_designs + 1, n_columns).transpose(1, 2, 0))
    sizes = np.diff(np.r_[class_start, n_designs])
    design_class = np.repeat(np.arange(len(class_start)), sizes)
    slack = (n + 3) * _U32
    factor = 2 * math.sqrt(n_columns) * slack + n_columns * slack**2 + 4 * (n_columns + 1) * _U32
    return OneFrameBases(np.ascontiguousarray(q[:, :-n_columns], dtype=np.float32), exact, design_class, factor)


def screened_residuals(
    d: np.ndarray, bases: OneFrameBases, class_start: np.ndarray, unit: float, none_bonus: float
) -> tuple[np.ndarray, float]:
    """Each class's smallest residual sum of squares (K,) and the lines' (no contact) for one
    centred curve ``d`` (N,): the float64 values where the class can matter (see the module
    docstring), the screened ones elsewhere. ``unit``: the scores' ``2 sigma^2``; ``none_bonus``:
    the no-contact score's bonus."""
    n_columns = bases.exact.shape[1]
    dd = float(np.einsum("i,i->", d, d))
    exact_lines = bases.exact[-1] @ d
    lines = dd - float(exact_lines @ exact_lines)
    p = d.astype(np.float32) @ bases.screen
    p *= p
    by_design = p.reshape(-1, n_columns)
    fitted = by_design[:, 0].copy()
    for column in range(1, n_columns):  # float32 sums (in the bound); a float64 reduction: 6x slower
        fitted += by_design[:, column]
    screened = np.float64(dd) - fitted  # float64
    class_min = np.minimum.reduceat(screened, class_start)
    bound = bases.error_factor * dd
    best = max(-float(class_min.min()), -lines + none_bonus * unit)  # in rss units, higher is better
    relevant = -class_min >= best - RELEVANT * unit - 2 * bound
    near = screened <= (class_min + 2 * bound)[bases.design_class]
    candidates = np.flatnonzero(near & relevant[bases.design_class])
    exact = bases.exact[candidates] @ d  # (k, L)
    exact *= exact
    rss = dd - exact[:, 0]
    for column in range(1, n_columns):  # the batch path's order of the subtractions
        rss -= exact[:, column]
    class_min[relevant] = np.inf
    np.minimum.at(class_min, bases.design_class[candidates], rss)
    return class_min, lines
