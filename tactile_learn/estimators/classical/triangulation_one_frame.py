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
loads are all below the valid load is answered at once with a new row of zeros; a frame with one
valid sensor at once from that sensor (the contact on it: what every candidate triangle's fallback
gives). The results equal the batch path's to rounding (the same formulas in the same order;
``pow`` and friends may differ in the last bit from numpy's), which the tests check on many frames.

At batch 1 a frame's cost is the number of bytecodes it runs, and more so on the first frames after
other work (a batch, another program): those run several times slower while the interpreter's
paths refill. :func:`frame_predictor` is therefore one function for the whole frame, with the
steps that wrap others written out.
"""

from __future__ import annotations

import math
import struct
from array import array
from collections.abc import Callable, Sequence
from operator import itemgetter
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the batch module imports this one
    from tactile_learn.estimators.classical.triangulation import LoadModel, TriangleGeometry
    from tactile_learn.fsr_one_frame import OneFrameCheck

__all__ = ["OneFrameTriangulation", "frame_predictor"]


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
        #: what _solve reads on every call, in one tuple (one attribute look-up)
        self._constants = (
            self.min_load,
            self.low_load**self.neg_inv_m,  # g of a sensor below the valid load (low_load >= 1e-9)
            self.neg_inv_m,
            self.on_axis,
            self.inside_depth,
            float(model.m),
            float(model.c),
            float(model.force_scale),
            float(model.force_exponent),
        )
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
        #: each triangle's constants, flat: its sensors, the closed form's matrix and vectors, its
        #: first corner, the barycentric matrix, gamma, its corners
        self.triangles: list[tuple] = []
        for t in range(4):
            (a00, a01), (a10, a11) = geometry.a_inv[t].tolist()
            (b00, b01), (b10, b11) = geometry.bary_inv[t].tolist()
            corners = geometry.corners[t].tolist()
            gamma = float((geometry.u[t] ** 2).sum() + self.h2)  # > 0
            self.triangles.append(
                (
                    itemgetter(*(int(i) for i in geometry.tris[t])),
                    a00, a01, a10, a11,
                    *geometry.u[t].tolist(),
                    *geometry.x0[t].tolist(),
                    *corners[0],
                    b00, b01, b10, b11,
                    gamma,
                    corners,
                )
            )  # fmt: skip
        #: by the frame's valid sensors (bit k: sensor k at or above the valid load), the triangles
        #: with the most of them: the winner is one of these (see :meth:`winner`). Where one sensor
        #: alone is valid, every candidate gives the same answer (each triangle's fallback for fewer
        #: than two valid sensors puts the contact on its strongest sensor, that one, with the same
        #: force): only the first is kept, and :attr:`lone_sensor` names the sensor and its position
        sensors = [[int(i) for i in tri] for tri in geometry.tris]
        self.candidates: list[tuple[int, ...]] = []
        self.lone_sensor: list[tuple[int, float, float] | None] = []
        for mask in range(1 << 6):  # six sensors
            counts = [sum(mask >> i & 1 for i in tri) for tri in sensors]
            chosen = tuple(t for t, n in enumerate(counts) if n == max(counts))
            lone = None
            if mask and not mask & (mask - 1):  # one bit: one valid sensor
                chosen = chosen[:1]
                k = mask.bit_length() - 1
                x, y = self.triangles[chosen[0]][-1][sensors[chosen[0]].index(k)]  # its corner, as _solve reads it
                lone = (k, x, y)
            self.candidates.append(chosen)
            self.lone_sensor.append(lone)

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

    def _solve(self, loads: Sequence[float], tri: tuple) -> tuple[float, float, float, int, bool, float, float]:
        """One triangle's closed form with the fallbacks (``solve_triangles`` for one frame):
        x, y, force, valid sensors, inside, depth, summed load. (``min`` and ``max`` of two or
        three numbers written out as comparisons: the same first-of-equals and NaN behaviour.)"""
        pick, a00, a01, a10, a11, u0, u1, x00, x01, cx, cy, b00, b01, b10, b11, gamma, corners = tri
        min_load, g_low, power, on_axis, inside_depth, m, c, scale, exponent = self._constants
        f0, f1, f2 = pick(loads)
        n_valid = (f0 >= min_load) + (f1 >= min_load) + (f2 >= min_load)
        total = f0 + f1 + f2
        if n_valid <= 1:  # put the contact on the strongest sensor (the batch path's fallback)
            f = (f0, f1, f2)
            strongest = _argmax(f)
            force = max(f[strongest], 0.0) / on_axis
            x, y = corners[strongest]
            return x, y, (force if math.isfinite(force) else 0.0), n_valid, False, 0.0, total
        # g = max(f or the low load, 1e-9) ** power, with the low load's worked out once
        g0 = (1e-9 if f0 < 1e-9 else f0) ** power if f0 >= min_load else g_low
        dg0 = ((1e-9 if f1 < 1e-9 else f1) ** power if f1 >= min_load else g_low) - g0
        dg1 = ((1e-9 if f2 < 1e-9 else f2) ** power if f2 >= min_load else g_low) - g0
        x1x = a00 * dg0 + a01 * dg1
        x1y = a10 * dg0 + a11 * dg1
        alpha = x1x * x1x + x1y * x1y
        beta = 2.0 * (u0 * x1x + u1 * x1y) - g0
        disc = beta * beta - 4.0 * alpha * gamma
        if alpha <= 1e-12 * max(beta * beta, 1e-300):  # three equal loads: the linear root
            k1 = k2 = -gamma / (beta if abs(beta) > 1e-300 else -1e-300)
        elif disc < 0:  # noise: the parabola's vertex (least residual)
            k1 = k2 = -beta / (2 * alpha)
        else:
            sq = math.sqrt(disc)
            k1, k2 = (-beta - sq) / (2 * alpha), (-beta + sq) / (2 * alpha)
        # the first root, then the second where it lies deeper inside (the batch path's argmax:
        # the first of equals); depth: the smallest barycentric coordinate (> 0 inside)
        k = x = y = depth = math.nan
        for root in (k1, k2) if k2 != k1 else (k1,):  # (equal roots: the same point, the first wins)
            root_x, root_y = x00 + root * x1x, x01 + root * x1y
            ex, ey = root_x - cx, root_y - cy
            l1, l2 = b00 * ex + b01 * ey, b10 * ex + b11 * ey
            # K = (C P)^(1/m) > 0: a root that is not positive is no point
            root_depth = min(1.0 - (l1 + l2), l1, l2) if root > 0 else -math.inf
            if root is k1 or root_depth > depth:
                k, x, y, depth = root, root_x, root_y, root_depth
        try:  # LoadModel.force on a float; an overflow is inf, as numpy's (then zeroed)
            force = scale * ((0.0 if k < 0.0 else k) ** m / c) ** exponent  # (max(k, 0.0))
        except OverflowError:
            force = math.inf
        return x, y, (force if math.isfinite(force) else 0.0), n_valid, depth >= inside_depth, depth, total

    def estimate(self, codes: list[float]) -> list[float]:
        """The five columns of one frame (``x, y, force, p_contact, p_inside``)."""
        return self.estimate_loads(self.loads(codes))

    def estimate_loads(self, loads: list[float]) -> list[float]:
        """:meth:`estimate` from the frame's six disc loads (N)."""
        valid = self.valid(loads)
        return [0.0, 0.0, 0.0, 0.0, 0.0] if not valid else self.estimate_valid(loads, valid)

    def valid(self, loads: list[float]) -> int:
        """The frame's valid sensors as bits (bit k: sensor k's load at or above the valid load);
        0 for a frame without contact. (Another load model on the same film, geometry and valid
        load shares it: :meth:`estimate_valid` of either.)"""
        m = self.min_load
        l0, l1, l2, l3, l4, l5 = loads
        return (l0 >= m) | (l1 >= m) << 1 | (l2 >= m) << 2 | (l3 >= m) << 3 | (l4 >= m) << 4 | (l5 >= m) << 5

    def estimate_valid(self, loads: list[float], valid: int) -> list[float]:
        """The five columns of a frame with contact (``valid``: its :meth:`valid`, not 0)."""
        x, y, force, n_valid, inside, _, _ = self.winner(loads, valid)
        return [x, y, force, 1.0, 0.5 if n_valid <= 1 else float(inside)]

    def winner(self, loads: Sequence[float], valid: int) -> tuple[float, float, float, int, bool, float, float]:
        """The winning triangle's :meth:`_solve` of a frame with contact (``valid``: its
        :meth:`valid`, not 0).

        Only the triangles with the most valid sensors are solved: the winner's score counts its
        valid sensors in millions and everything else below 102,000, so no other triangle can win
        (and where only one triangle has the most, it wins without a score).
        """
        candidates = self.candidates[valid]
        if len(candidates) == 1:  # one candidate (most frames with contact)
            return self._solve(loads, self.triangles[candidates[0]])
        return self._best_scored(loads, candidates)

    def _best_scored(
        self, loads: Sequence[float], candidates: tuple[int, ...]
    ) -> tuple[float, float, float, int, bool, float, float]:
        """The best-scoring solution among the triangles with the most valid sensors."""
        # the summed loads are scaled by the largest of all four triangles' (as the batch path)
        top = 1e-300
        for tri in self.triangles:
            f0, f1, f2 = tri[0](loads)
            total = f0 + f1 + f2  # as _solve sums it
            top = total if total > top else top
        best: tuple[float, float, float, int, bool, float, float] | None = None
        best_score = 0.0
        solve, triangles = self._solve, self.triangles
        for t in candidates:
            s = solve(loads, triangles[t])
            # most valid sensors, then inside, then the largest summed load (rounded as np.round
            # does: scaled, rounded half to even), then the deepest inside; the first of equals
            depth = s[5]
            depth = -1.0 if depth < -1.0 else 1.0 if depth > 1.0 else depth
            score = s[3] * 1e6 + s[4] * 1e5 + round(s[6] / top * 1e3) / 1e3 * 1e3 + depth
            if best is None or score > best_score:
                best, best_score = s, score
        assert best is not None  # the triangles with the most valid sensors: at least one
        return best


_FLOAT32 = np.dtype(np.float32)
_ROW = (1, 6)  # a single frame's result: x, y, force, p_contact, p_inside, p_one_press
# into and out of a float32 row's buffer: native float32, numpy's cast (round to nearest)
_PACK_ROW: Callable[..., None] = struct.Struct("6f").pack_into
_PACK_FLAG: Callable[..., None] = struct.Struct("f").pack_into
_UNPACK_POINT: Callable[..., tuple[float, ...]] = struct.Struct("3f").unpack_from
_POINT = struct.Struct("3f")


def _float32_point(x: float, y: float, force: float) -> tuple[float, ...]:
    """``x, y, force`` rounded to float32 as numpy rounds them (beyond float32's range: inf)."""
    try:
        return _POINT.unpack(_POINT.pack(x, y, force))
    except OverflowError:
        return tuple(array("f", (x, y, force)))


def frame_predictor(
    one: OneFrameTriangulation, check: OneFrameCheck, screen: OneFrameTriangulation | None = None
) -> Callable[..., np.ndarray]:
    """The single-frame answer ``(1, 6)`` float32 (the batch path's ``predict_checked`` for one
    frame) from the frame's six codes and disc loads (``whole``: the codes are known to be whole
    ADC codes, as the keys of the code -> load table are): the estimate, rounded to float32 in the
    output row, the one-press check on the rounded estimate (as the batch path reads it) and, for
    the half-space kernel, the fitted kernel's solution of the same loads as the check's screen
    (``screen``: the same film, geometry and valid load, so the same valid sensors).

    One function for the whole frame: the valid sensors, the winning triangle (:meth:`~OneFrameTriangulation.winner`)
    and the check's first test (:meth:`~tactile_learn.fsr_one_frame.OneFrameCheck.passes_at`)
    written out here rather than called through the methods that wrap them (each call level and
    intermediate list costs, and more so on the first frames after other work has run)."""
    min_load, candidates, triangles, lone_sensor = one.min_load, one.candidates, one.triangles, one.lone_sensor
    on_axis = one.on_axis
    solve, best_scored = one._solve, one._best_scored
    screen_winner = None if screen is None else screen.winner
    measured_of, measured_of_whole, scale_of = check.measured, check.measured_of_whole, check._scale
    passes_at, flag_refined = check.passes_at, check.flag_refined
    zeros, empty = np.zeros, np.empty

    def predict_loads(codes: list[float], loads: Sequence[float], whole: bool = False) -> np.ndarray:
        l0, l1, l2, l3, l4, l5 = loads
        m = min_load
        valid = (l0 >= m) | (l1 >= m) << 1 | (l2 >= m) << 2 | (l3 >= m) << 3 | (l4 >= m) << 4 | (l5 >= m) << 5
        if not valid:  # no contact (a NaN load is no valid sensor either): every column 0
            return zeros(_ROW, _FLOAT32)
        lone = lone_sensor[valid]
        if lone is not None:  # one valid sensor: the contact on it (_solve's fallback), not checked
            k, x, y = lone
            force = max(loads[k], 0.0) / on_axis
            force, p_inside = force if math.isfinite(force) else 0.0, 0.5
        else:
            chosen = candidates[valid]  # (OneFrameTriangulation.winner written out)
            if len(chosen) == 1:
                x, y, force, n_valid, inside, _, _ = solve(loads, triangles[chosen[0]])
            else:
                x, y, force, n_valid, inside, _, _ = best_scored(loads, chosen)
            p_inside = 0.5 if n_valid <= 1 else float(inside)
        out = empty(_ROW, _FLOAT32)
        try:
            _PACK_ROW(out, 0, x, y, force, 1.0, p_inside, 0.5)
        except OverflowError:  # beyond float32's range: inf, as numpy's cast
            out[0] = array("f", (x, y, force, 1.0, p_inside, 0.5)).tolist()
        if p_inside > 0.5:  # (else 0.5: outside the triangles or undecided, not checked)
            x, y, force = _UNPACK_POINT(out)
            measured = measured_of_whole(codes) if whole else measured_of(codes)
            scale = scale_of(measured)
            if screen_winner is None:  # the estimate as it is first
                first = passes_at(measured, scale, x, y, force)
            else:  # the screen's point as it is first (OneFrameCheck.flag_inside)
                sx, sy, sforce, _, _, _, _ = screen_winner(loads, valid)
                first = passes_at(measured, scale, *_float32_point(sx, sy, sforce))
            if first:
                _PACK_FLAG(out, 20, 1.0)
            else:
                _PACK_FLAG(out, 20, flag_refined(measured, scale, x, y, force, screen_winner is not None))
        return out

    return predict_loads
