"""Triangulation (:mod:`.triangulation`) of a single frame, on Python floats.

The batch path is vectorised over frames and the four triangles: some hundred numpy calls, each
with a microsecond or so of fixed cost, for arithmetic that takes ~2-3 us per frame at batch 1024.
:class:`OneFrameTriangulation` does the same steps for one frame on plain floats, with everything
that depends only on the film worked out once: the disc load of every ADC code (the batch path's
own readout inverse applied to the codes 0 .. full scale, so whole codes give its loads bit for
bit), the triangles' matrices as tuples, the load model's constants. A frame whose six loads are
all below the valid load is answered at once (no contact, all zeros). The results equal the batch
path's to rounding (the same formulas in the same order; ``pow`` and friends may differ in the
last bit from numpy's), which the tests check on many frames.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the batch module imports this one
    from tactile_learn.estimators.classical.triangulation import LoadModel, TriangleGeometry

__all__ = ["OneFrameTriangulation"]


def _argmax(values: list[float]) -> int:
    """Index of the first largest value (``np.argmax`` on numbers without NaN)."""
    best = 0
    for i in range(1, len(values)):
        if values[i] > values[best]:
            best = i
    return best


class OneFrameTriangulation:
    """``triangulate`` of :mod:`.triangulation` for one frame of six readings (module docstring)."""

    def __init__(
        self,
        geometry: TriangleGeometry,
        model: LoadModel,
        min_load_n: float,
        fallback_fraction: float,
        inside_tol_mm: float,
        loads_of_codes: np.ndarray,
        loads_from_readings: Callable[[np.ndarray], np.ndarray],
    ) -> None:
        self.model = model
        self.min_load = float(min_load_n)
        self.low_load = max(float(fallback_fraction) * self.min_load, 1e-9)  # as solve_triangles' clamp
        self.inside_depth = -float(inside_tol_mm) / geometry.height_mm
        self.neg_inv_m = -1.0 / model.m
        self.h2 = model.h_mm**2
        self.on_axis = max(model.on_axis, 1e-300)
        self.loads_of_codes = loads_of_codes.tolist()
        self.loads_from_readings = loads_from_readings
        self.triangles = []
        for t in range(4):
            a_inv, u, x0, corners, bary = (
                geometry.a_inv[t].tolist(),
                geometry.u[t].tolist(),
                geometry.x0[t].tolist(),
                geometry.corners[t].tolist(),
                geometry.bary_inv[t].tolist(),
            )
            gamma = float((geometry.u[t] ** 2).sum() + self.h2)  # > 0
            self.triangles.append((tuple(int(i) for i in geometry.tris[t]), a_inv, u, x0, corners, bary, gamma))

    def loads(self, codes: list[float]) -> list[float]:
        """Disc loads (N) of six ADC codes: whole codes from the table, others by the batch inverse."""
        table = self.loads_of_codes
        top = len(self.loads_of_codes)  # codes a checked frame can hold; others (unchecked) by the batch inverse
        if all(c.is_integer() and 0 <= c < top for c in codes):
            return [table[int(c)] for c in codes]
        return [float(v) for v in self.loads_from_readings(np.array([codes]))[0]]

    def _force(self, k: float) -> float:
        """:meth:`LoadModel.force` on a float; an overflow is inf, as numpy's (then zeroed)."""
        model = self.model
        try:
            raw = max(k, 0.0) ** model.m / model.c
            return float(model.force_scale * raw**model.force_exponent)
        except OverflowError:
            return math.inf

    def _solve(self, f: list[float], tri: tuple) -> tuple[float, float, float, int, bool, float, float]:
        """One triangle's closed form with the fallbacks (``solve_triangles`` for one frame):
        x, y, force, valid sensors, inside, depth, summed load."""
        _, a_inv, u, x0, corners, bary, gamma = tri
        n_valid = (f[0] >= self.min_load) + (f[1] >= self.min_load) + (f[2] >= self.min_load)
        total = f[0] + f[1] + f[2]
        if n_valid <= 1:  # put the contact on the strongest sensor (the batch path's fallback)
            strongest = _argmax(f)
            force = max(f[strongest], 0.0) / self.on_axis
            x, y = corners[strongest]
            return x, y, (force if math.isfinite(force) else 0.0), n_valid, False, 0.0, total
        g0, g1, g2 = (max(v if v >= self.min_load else self.low_load, 1e-9) ** self.neg_inv_m for v in f)
        dg0, dg1 = g1 - g0, g2 - g0
        x1x = a_inv[0][0] * dg0 + a_inv[0][1] * dg1
        x1y = a_inv[1][0] * dg0 + a_inv[1][1] * dg1
        alpha = x1x * x1x + x1y * x1y
        beta = 2.0 * (u[0] * x1x + u[1] * x1y) - g0
        disc = beta * beta - 4.0 * alpha * gamma
        if alpha <= 1e-12 * max(beta * beta, 1e-300):  # three equal loads: the linear root
            roots: tuple[float, ...] = (-gamma / (beta if abs(beta) > 1e-300 else -1e-300),) * 2
        elif disc < 0:  # noise: the parabola's vertex (least residual)
            roots = (-beta / (2 * alpha),) * 2
        else:
            sq = math.sqrt(disc)
            roots = ((-beta - sq) / (2 * alpha), (-beta + sq) / (2 * alpha))
        best: tuple[float, float, float, float] | None = None
        for k in roots:
            x, y = x0[0] + k * x1x, x0[1] + k * x1y
            ex, ey = x - corners[0][0], y - corners[0][1]
            l1 = bary[0][0] * ex + bary[0][1] * ey
            l2 = bary[1][0] * ex + bary[1][1] * ey
            depth = min(1.0 - (l1 + l2), l1, l2) if k > 0 else -math.inf  # K = (C P)^(1/m) > 0
            if best is None or depth > best[3]:
                best = (k, x, y, depth)
        assert best is not None
        k, x, y, depth = best
        force = self._force(k)
        return x, y, (force if math.isfinite(force) else 0.0), n_valid, depth >= self.inside_depth, depth, total

    def estimate(self, codes: list[float]) -> list[float]:
        """The five columns of one frame (``x, y, force, p_contact, p_inside``)."""
        loads = self.loads(codes)
        if not max(loads) >= self.min_load:  # no contact: all outputs 0
            return [0.0, 0.0, 0.0, 0.0, 0.0]
        solved = [self._solve([loads[i] for i in tri[0]], tri) for tri in self.triangles]
        top = max(max(s[6] for s in solved), 1e-300)
        # winner: most valid sensors, then inside, then the largest summed load (rounded as
        # np.round does: scaled, rounded half to even), then the deepest inside
        scores = [
            s[3] * 1e6 + s[4] * 1e5 + round(s[6] / top * 1e3) / 1e3 * 1e3 + min(max(s[5], -1.0), 1.0) for s in solved
        ]
        x, y, force, n_valid, inside, _, _ = solved[_argmax(scores)]
        return [x, y, force, 1.0, 0.5 if n_valid <= 1 else float(inside)]
