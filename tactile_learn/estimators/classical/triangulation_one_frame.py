"""Triangulation (:mod:`.triangulation`) of a single frame, on Python floats.

The batch path is vectorised over frames and the four triangles: some hundred numpy calls, each
with a microsecond or so of fixed cost, for arithmetic that takes ~2-3 us per frame at batch 1024.
:class:`OneFrameTriangulation` does the same steps for one frame on plain floats, with everything
that depends only on the film worked out once: the disc load of every ADC code (the batch path's
own readout inverse applied to the codes 0 .. full scale, so whole codes give its loads bit for
bit), the triangles' matrices as tuples, the load model's constants. The loads are also kept by
code for the whole codes the input check passes (:attr:`OneFrameTriangulation.load_of_code`): six
dictionary look-ups check a frame and give its loads at once (a NaN, an infinite, saturated,
negative or fractional code is no key: such a frame takes the general check). A frame whose six
loads are all below the valid load is answered at once (no contact, all zeros). The results equal the batch
path's to rounding (the same formulas in the same order; ``pow`` and friends may differ in the
last bit from numpy's), which the tests check on many frames.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from operator import itemgetter
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the batch module imports this one
    from tactile_learn.estimators.classical.triangulation import LoadModel, TriangleGeometry

__all__ = ["Choice", "OneFrameTriangulation"]

#: a frame's triangle choice (:meth:`OneFrameTriangulation.choice`): each triangle's three loads,
#: each triangle's valid sensors, the most of them, the largest summed load
Choice = tuple[list[tuple[float, float, float]], list[int], int, float]


def _argmax(values: list[float] | tuple[float, ...]) -> int:
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
        valid_codes: tuple[float, float, bool] | None = None,
    ) -> None:
        self.model = model
        self.min_load = float(min_load_n)
        self.low_load = max(float(fallback_fraction) * self.min_load, 1e-9)  # as solve_triangles' clamp
        self.inside_depth = -float(inside_tol_mm) / geometry.height_mm
        self.neg_inv_m = -1.0 / model.m
        self.h2 = model.h_mm**2
        self.on_axis = max(model.on_axis, 1e-300)
        self.loads_of_codes_array = loads_of_codes
        self.loads_of_codes = loads_of_codes.tolist()
        self.loads_from_readings = loads_from_readings
        #: the disc load of every whole code that the input check passes as it is (``valid_codes``:
        #: its ``(low, high, strict)`` bounds; none for a film whose readings it maps): a frame
        #: whose six codes are all keys needs no other check (NaN, inf, out of range, non-whole
        #: codes are not keys and take the general path)
        self.load_of_code: dict[float, float] = {}
        if valid_codes is not None:
            low, high, strict = valid_codes
            self.load_of_code = {
                float(code): load
                for code, load in enumerate(self.loads_of_codes)
                if (low < code if strict else low <= code) and code < high
            }
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
        self._pick = [itemgetter(*tri[0]) for tri in self.triangles]  # a triangle's three loads

    def loads(self, codes: list[float]) -> list[float]:
        """Disc loads (N) of six ADC codes: whole codes from the table, others by the batch inverse."""
        by_code = self.load_of_code
        try:
            return [by_code[c] for c in codes]
        except KeyError:  # a code outside the checked range (a calibrated film: every code) or not whole
            pass
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

    def _solve(self, f: tuple[float, float, float], tri: tuple) -> tuple[float, float, float, int, bool, float, float]:
        """One triangle's closed form with the fallbacks (``solve_triangles`` for one frame):
        x, y, force, valid sensors, inside, depth, summed load."""
        _, a_inv, u, x0, corners, bary, gamma = tri
        f0, f1, f2 = f
        min_load = self.min_load
        n_valid = (f0 >= min_load) + (f1 >= min_load) + (f2 >= min_load)
        total = f0 + f1 + f2
        if n_valid <= 1:  # put the contact on the strongest sensor (the batch path's fallback)
            strongest = _argmax(f)
            force = max(f[strongest], 0.0) / self.on_axis
            x, y = corners[strongest]
            return x, y, (force if math.isfinite(force) else 0.0), n_valid, False, 0.0, total
        low, power = self.low_load, self.neg_inv_m
        g0 = max(f0 if f0 >= min_load else low, 1e-9) ** power
        dg0 = max(f1 if f1 >= min_load else low, 1e-9) ** power - g0
        dg1 = max(f2 if f2 >= min_load else low, 1e-9) ** power - g0
        (a00, a01), (a10, a11) = a_inv
        x1x = a00 * dg0 + a01 * dg1
        x1y = a10 * dg0 + a11 * dg1
        alpha = x1x * x1x + x1y * x1y
        beta = 2.0 * (u[0] * x1x + u[1] * x1y) - g0
        disc = beta * beta - 4.0 * alpha * gamma
        if alpha <= 1e-12 * max(beta * beta, 1e-300):  # three equal loads: the linear root
            k1 = k2 = -gamma / (beta if abs(beta) > 1e-300 else -1e-300)
        elif disc < 0:  # noise: the parabola's vertex (least residual)
            k1 = k2 = -beta / (2 * alpha)
        else:
            sq = math.sqrt(disc)
            k1, k2 = (-beta - sq) / (2 * alpha), (-beta + sq) / (2 * alpha)
        (cx, cy), (b00, b01), (b10, b11) = corners[0], bary[0], bary[1]
        # the first root, then the second where it lies deeper inside (the batch path's argmax:
        # the first of equals)
        x, y = x0[0] + k1 * x1x, x0[1] + k1 * x1y
        ex, ey = x - cx, y - cy
        l1, l2 = b00 * ex + b01 * ey, b10 * ex + b11 * ey
        depth = min(1.0 - (l1 + l2), l1, l2) if k1 > 0 else -math.inf  # K = (C P)^(1/m) > 0
        k = k1
        x2, y2 = x0[0] + k2 * x1x, x0[1] + k2 * x1y
        ex, ey = x2 - cx, y2 - cy
        l1, l2 = b00 * ex + b01 * ey, b10 * ex + b11 * ey
        depth2 = min(1.0 - (l1 + l2), l1, l2) if k2 > 0 else -math.inf
        if depth2 > depth:
            k, x, y, depth = k2, x2, y2, depth2
        force = self._force(k)
        return x, y, (force if math.isfinite(force) else 0.0), n_valid, depth >= self.inside_depth, depth, total

    def estimate(self, codes: list[float]) -> list[float]:
        """The five columns of one frame (``x, y, force, p_contact, p_inside``)."""
        return self.estimate_loads(self.loads(codes))

    def estimate_loads(self, loads: list[float]) -> list[float]:
        """:meth:`estimate` from the frame's six disc loads (N)."""
        choice = self.choice(loads)
        return [0.0, 0.0, 0.0, 0.0, 0.0] if choice is None else self.estimate_choice(choice)

    def choice(self, loads: list[float]) -> Choice | None:
        """What the triangle choice reads besides the load model: every triangle's three loads and
        valid sensors, the most valid sensors of any triangle and the largest summed load; none
        for a frame without contact. (Another load model on the same film, geometry and valid load
        shares it: :meth:`estimate_choice` of either.)"""
        min_load = self.min_load
        if not max(loads) >= min_load:  # no contact: all outputs 0
            return None
        picked = [pick(loads) for pick in self._pick]
        valid, most, top = [], 0, 1e-300  # every triangle's valid sensors; the largest summed load
        for f0, f1, f2 in picked:
            n_valid = (f0 >= min_load) + (f1 >= min_load) + (f2 >= min_load)
            valid.append(n_valid)
            most = n_valid if n_valid > most else most
            total = f0 + f1 + f2  # as _solve sums it
            top = total if total > top else top
        return picked, valid, most, top

    def estimate_choice(self, choice: Choice) -> list[float]:
        """The five columns of a frame with contact from its :meth:`choice`.

        Only the triangles with the most valid sensors are solved: the winner's score counts its
        valid sensors in millions and everything else below 102,000, so no other triangle can win
        (and where only one triangle has the most, it wins without a score).
        """
        picked, valid, most, top = choice
        if valid.count(most) == 1:  # one candidate (most frames with contact)
            t = valid.index(most)
            best = self._solve(picked[t], self.triangles[t])
        else:
            best = self._best_scored(picked, valid, most, top)
        x, y, force, n_valid, inside, _, _ = best
        return [x, y, force, 1.0, 0.5 if n_valid <= 1 else float(inside)]

    def _best_scored(
        self, picked: list[tuple[float, float, float]], valid: list[int], most: int, top: float
    ) -> tuple[float, float, float, int, bool, float, float]:
        """The best-scoring solution among the triangles with the most valid sensors."""
        best: tuple[float, float, float, int, bool, float, float] | None = None
        best_score = 0.0
        solve, triangles = self._solve, self.triangles
        for t in range(4):
            if valid[t] != most:
                continue
            s = solve(picked[t], triangles[t])
            # most valid sensors, then inside, then the largest summed load (rounded as np.round
            # does: scaled, rounded half to even), then the deepest inside; the first of equals
            depth = s[5]
            depth = -1.0 if depth < -1.0 else 1.0 if depth > 1.0 else depth
            score = s[3] * 1e6 + s[4] * 1e5 + round(s[6] / top * 1e3) / 1e3 * 1e3 + depth
            if best is None or score > best_score:
                best, best_score = s, score
        assert best is not None  # the triangles with the most valid sensors: at least one
        return best
