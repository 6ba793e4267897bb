"""The one-press check (:mod:`tactile_learn.fsr_check`) on a single frame, in plain Python floats.

At batch 1 the check's numpy arithmetic works on arrays of six (or eighteen) numbers, where every
numpy call costs a microsecond or so of fixed overhead: the forward model alone is some twenty
calls, and a Levenberg-Marquardt step three of them. A light press that needs refining then cost
~1-2 ms per frame. :class:`OneFrameCheck` does the same arithmetic on Python floats with the
film's tables as lists, built once per check: the same forward model (distance, Hertz radius,
bilinear lookup of the load path, far-field point-load formula, the FSR law), the same
analytic Jacobian, damping schedule, step limits and early stop, so the verdicts equal the batch
path's (the misfits agree to rounding: a 3 x 3 solve by elimination instead of LAPACK).
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from tactile_learn.fsr_check import OnePressCheck

__all__ = ["OneFrameCheck", "expit"]

_STEP_LIMIT = (5.0, 5.0, 1.0)  # as fsr_check._STEP_LO/_STEP_HI: a step's largest move
_FORCE_FLOOR = float(np.float32(1e-3))  # the batch path clips the float32 force at 1e-3 (N)


def _log_force(force: float) -> float:
    """log of a float32 force (N) clipped at 1 mN, in float64 (as the batch path's ``_log_force``;
    a numpy scalar's log cost more than the rest of a press's screen)."""
    return math.log(max(force, _FORCE_FLOOR))


def expit(z: float) -> float:
    """The logistic function as scipy computes it, ``1 / (1 + exp(-z))``; where ``exp(-z)``
    overflows (``math.exp`` raises, numpy gives inf) the result is 0, as numpy's."""
    try:
        return 1.0 / (1.0 + math.exp(-z))
    except OverflowError:
        return 0.0


def _solve_spd3(
    a00: float, a01: float, a02: float, a11: float, a12: float, a22: float, b0: float, b1: float, b2: float
) -> tuple[float, float, float]:
    """``A x = b`` for a symmetric positive definite 3 x 3 ``A`` (the damped normal equations:
    ``J^T J`` plus a positive ridge), by elimination without pivoting (stable for such matrices);
    a zero pivot (no information at all) gives no step."""
    if a00 == 0.0:
        return 0.0, 0.0, 0.0
    m1, m2 = a01 / a00, a02 / a00
    c11, c12, d1 = a11 - m1 * a01, a12 - m1 * a02, b1 - m1 * b0
    c21, c22, d2 = a12 - m2 * a01, a22 - m2 * a02, b2 - m2 * b0
    if c11 == 0.0:
        return 0.0, 0.0, 0.0
    m3 = c21 / c11
    e22, f2 = c22 - m3 * c12, d2 - m3 * d1
    if e22 == 0.0:
        return 0.0, 0.0, 0.0
    x2 = f2 / e22
    x1 = (d1 - c12 * x2) / c11
    return (b0 - a01 * x1 - a02 * x2) / a00, x1, x2


class OneFrameCheck:
    """:class:`~tactile_learn.fsr_check.OnePressCheck`'s arithmetic for one frame (module docstring)."""

    def __init__(self, check: OnePressCheck) -> None:
        config, _, readout, tip = check._model
        transfer, positions = check._path
        self.threshold = float(check.threshold)
        self.steps = int(check.steps)
        self.floor_us = float(check.floor_us)
        self.positions = [(float(x), float(y)) for x, y in positions]
        if len(self.positions) != 6:  # the misfit's sums are written out for the film's six sensors
            raise ValueError(f"the one-frame check is written for six sensors, got {len(self.positions)}")
        lay, el = config.layout, config.element
        e_star = lay.youngs_modulus_mpa / (1.0 - lay.poisson**2)  # as fsr.hertz_radius_mm
        self.tip, self.e_star = float(tip), float(e_star)
        dg, ag = transfer.d_grid, transfer.a_grid
        self.d0, self.dd, self.d_top = float(dg[0]), float(dg[1] - dg[0]), float(len(dg) - 1.000001)
        self.a0, self.da, self.a_top = float(ag[0]), float(ag[1] - ag[0]), float(len(ag) - 1.000001)
        self.d_max = float(dg[-1])
        if dg[0] != 0.0 or ag[0] != 0.0:  # conductance_at leaves out the clamps below the grids' start
            raise ValueError("the film's load table must start at distance 0 and radius 0")
        if float(transfer.table.min()) < 0.0:  # conductance_at leaves out the clamp of the load at 0
            raise ValueError("the film's load table must not be negative")
        self.table = transfer.table.tolist()
        #: the table by column (radius): a force fixes two columns, read at two distances per sensor.
        #: Packed doubles rather than lists of floats: a sensor's four values lie in one or two
        #: cache lines, not in eight objects (in a stream, other work between frames evicts them:
        #: ~1 us a press, measured)
        self.columns = [array("d", column) for column in transfer.table.T.tolist()]
        self.transfer = transfer
        self.leak, self.per_n = float(el.leak_conductance_us), float(el.conductance_us_per_n)
        self.break_n, self.width_n, self.sat_n = (
            float(el.break_force_n),
            float(el.break_width_n),
            float(el.saturation_force_n),
        )
        levels = 2**readout.config.adc_bits
        # the readout inverse of every code, by the batch path's own function (bit for bit)
        self.code_conductance = readout.conductance_us(np.arange(levels, dtype=np.float64)).tolist()
        # the same by code, for a look-up that is also the check (NaN or a fractional code is no key)
        self.conductance_of_code = {float(code): g for code, g in enumerate(self.code_conductance)}
        #: and packed, for codes known to be whole and in range (:meth:`measured_of_whole`)
        self.code_conductance_packed = array("d", self.code_conductance)
        self.readout = readout
        #: what conductance_at reads on every call, in one tuple (one attribute look-up)
        self._constants = (
            tuple(self.positions),
            self.columns,
            self.dd,
            self.d_top,
            self.d_max,
            self.leak,
            self.per_n,
            self.break_n,
            self.width_n,
            self.sat_n,
        )

    # ---- the forward model ----------------------------------------------------------------------

    def column(self, log_force: float) -> tuple[float, float, int, float]:
        """What a press's force sets for all six sensors: the force (N), the Hertz radius (mm) and
        the load table's column position (index and fraction) of that radius."""
        force = math.exp(-10.0 if log_force < -10.0 else 6.0 if log_force > 6.0 else log_force)  # as the batch clip
        radius = (3.0 * force * self.tip / (4.0 * self.e_star)) ** (1.0 / 3.0)  # fsr.hertz_radius_mm
        ai = (radius - self.a0) / self.da
        ai = 0.0 if ai < 0.0 else self.a_top if ai > self.a_top else ai
        j0 = int(ai)
        return force, radius, j0, ai - j0

    def conductance(self, x: float, y: float, log_force: float) -> list[float]:
        """Modelled conductances (uS) of the six sensors for a press at ``x, y`` with ``log_force``
        (:meth:`OnePressCheck.conductance`; the same operations in the same order)."""
        return self.conductance_at(x, y, self.column(log_force))

    def conductance_at(self, x: float, y: float, column: tuple[float, float, int, float]) -> list[float]:
        """:meth:`conductance` with the force's part (:meth:`column`) worked out already (the
        finite differences in ``x`` and ``y`` share it). Written out with local names: this is
        the check's inner loop. The same operations in the same order as the batch path, less
        two that cannot change a bit here: the clamps below the grids' start (distances and radii
        are >= 0, the grids start at 0) and, for a load far above the break, the gate's logistic
        (``exp(-z) < 2**-53`` for ``z > 37``: ``1 / (1 + exp(-z))`` is exactly 1)."""
        exp, tanh, sqrt = math.exp, math.tanh, math.sqrt
        positions, columns, dd, d_top, d_max, leak, per_n, brk, width, sat = self._constants
        force, radius, j0, fj = column
        near, far = columns[j0], columns[j0 + 1]  # the load table's two columns of this radius
        gj = 1.0 - fj  # (a float constant: int - float takes a slower path; the same value)
        out = []
        for px, py in positions:
            dx, dy = x - px, y - py
            d = sqrt(dx * dx + dy * dy)
            if d > d_max:  # beyond the table: the far-field point-load formula (as per_newton)
                load = float(self.transfer.per_newton(np.array(d), np.array(radius))) * force
                if load < 0.0:
                    load = 0.0
            else:  # (the table and the weights are >= 0, the force > 0: the load is, no clamp)
                di = d / dd  # (d - 0) / dd
                if di > d_top:
                    di = d_top
                i0 = int(di)
                fi = di % 1.0  # di - i0 (di >= 0: both exact)
                gi = 1.0 - fi
                load = (near[i0] * gi * gj + near[i0 + 1] * fi * gj + far[i0] * gi * fj + far[i0 + 1] * fi * fj) * force
            z = (load - brk) / width
            if z > 37.0:  # the gate is exactly 1
                out.append(leak + per_n * (sat * tanh(load / sat)))
            else:
                try:
                    gate = 1.0 / (1.0 + exp(-z))  # expit
                except OverflowError:  # exp(-z) beyond float64's range: numpy's inf gives 0
                    gate = 0.0
                out.append(leak + per_n * (sat * tanh(load * gate / sat)))
        return out

    def model_and_normal_equations(
        self, x: float, y: float, log_force: float, column: tuple[float, float, int, float], measured: list[float]
    ) -> tuple[list[float], tuple[float, float, float, float, float, float, float, float, float]]:
        """A press's model conductances (:meth:`conductance_at`'s, bit for bit) and the
        Levenberg-Marquardt step's sums there (``column``: its :meth:`column`): ``J^T J`` (upper
        triangle, row by row) and ``J^T r`` (``r = measured - model``) for the analytic Jacobian
        ``J`` of the six conductances in ``(x, y, log force)``: :meth:`OnePressCheck.jacobian`'s
        derivatives on floats, summed over the sensors in order as the batch path's products (the
        tests compare them). One pass: the model's distances, look-ups and gate serve both. A
        sensor whose load is clamped at 0 has no slope and adds nothing to the sums."""
        tanh, sqrt, exp = math.tanh, math.sqrt, math.exp
        positions, columns, dd, d_top, d_max, leak, per_n, brk, width, sat = self._constants
        force, radius, j0, fj = column
        d_force = force if -10.0 <= log_force <= 6.0 else 0.0  # d F / d log F (0 along the clip)
        # d load / d log F = d F / d log F * (per_newton + d per_newton / d a * a / 3), a = cbrt(c F);
        # no slope in the radius where it is clamped to the table's last column
        radius_part = radius / 3.0 / self.da if radius / self.da < self.a_top else 0.0
        near, far = columns[j0], columns[j0 + 1]
        gj = 1.0 - fj
        model = []
        a00 = a01 = a02 = a11 = a12 = a22 = r0 = r1 = r2 = 0.0
        for (px, py), m in zip(positions, measured, strict=True):
            dx, dy = x - px, y - py
            d = sqrt(dx * dx + dy * dy)
            if d > d_max:
                per_newton = float(self.transfer.per_newton(np.array(d), np.array(radius)))  # as conductance_at
                slope_d, slope_a = self._far_field_slope(d), 0.0
                if per_newton < 0.0:  # (load clamped at 0 below)
                    per_newton = 0.0
            else:  # (>= 0, as conductance_at's: no clamp)
                di = d / dd
                d_free = di < d_top  # else clamped to the table's last row: no slope in distance
                if not d_free:
                    di = d_top
                i0 = int(di)
                fi = di % 1.0
                gi = 1.0 - fi
                t00, t10, t01, t11 = near[i0], near[i0 + 1], far[i0], far[i0 + 1]
                per_newton = t00 * gi * gj + t10 * fi * gj + t01 * gi * fj + t11 * fi * fj
                slope_d = ((t10 - t00) * gj + (t11 - t01) * fj) / dd if d_free else 0.0
                slope_a = (t01 - t00) * gi + (t11 - t10) * fi
            load = per_newton * force
            z = (load - brk) / width
            if z > 37.0:
                gate = 1.0
            else:
                try:
                    gate = 1.0 / (1.0 + exp(-z))
                except OverflowError:  # (as conductance_at)
                    gate = 0.0
            t = tanh(load * gate / sat)
            g = leak + per_n * (sat * t)
            model.append(g)
            if load > 0.0:
                dg_dload = per_n * (1.0 - t * t) * (gate + load * gate * (1.0 - gate) / width)
                along = dg_dload * force * slope_d / d if d > 0.0 else 0.0  # no direction on a sensor's centre
                jx, jy = along * dx, along * dy
                jf = dg_dload * d_force * (per_newton + slope_a * radius_part)
                resid = m - g
                a00, a01, a02 = a00 + jx * jx, a01 + jx * jy, a02 + jx * jf
                a11, a12, a22 = a11 + jy * jy, a12 + jy * jf, a22 + jf * jf
                r0, r1, r2 = r0 + jx * resid, r1 + jy * resid, r2 + jf * resid
        return model, (a00, a01, a02, a11, a12, a22, r0, r1, r2)

    def _far_field_slope(self, d: float) -> float:
        """The far-field point-load formula's slope in distance (disc load per newton per mm):
        ``k'(r) = -5 r k(r) / (r^2 + h^2)`` for each of its two Boussinesq terms."""
        transfer = self.transfer
        slope = 0.0
        for gain, depth in ((transfer.layer_gain, transfer.depth_mm), (transfer.share_gain, transfer.share_length_mm)):
            r2h2 = d * d + depth * depth
            slope -= gain * 5.0 * d * (3.0 * depth**3 / (2.0 * math.pi * r2h2**2.5)) / r2h2
        return math.pi * transfer.disc_radius_mm**2 * slope

    def measured(self, codes: list[float]) -> list[float]:
        """Conductances (uS) of ADC codes (the readout inverse; whole codes from its table)."""
        by_code = self.conductance_of_code
        try:
            return [by_code[c] for c in codes]
        except KeyError:  # a code outside the table or between two codes
            pass
        top = len(self.code_conductance)  # codes a checked frame can hold; others (unchecked) by the batch inverse
        if all(c.is_integer() and 0 <= c < top for c in codes):
            table = self.code_conductance
            return [table[int(c)] for c in codes]
        return [float(g) for g in self.readout.conductance_us(np.array(codes))]  # e.g. a calibrated film's

    def measured_of_whole(self, codes: list[float]) -> list[float]:
        """:meth:`measured` of six codes known to be whole ADC codes (a frame whose codes were
        all keys of a table of such codes): packed doubles rather than a dictionary's four
        objects a code, where other work between frames evicts them."""
        table = self.code_conductance_packed
        c0, c1, c2, c3, c4, c5 = codes
        return [table[int(c0)], table[int(c1)], table[int(c2)], table[int(c3)], table[int(c4)], table[int(c5)]]

    def _scale(self, measured: list[float]) -> float:
        """The misfit's denominator: RMS measured conductance plus the floor."""
        m0, m1, m2, m3, m4, m5 = measured  # six sensors, summed in order from the first (as numpy)
        return math.sqrt((m0 * m0 + m1 * m1 + m2 * m2 + m3 * m3 + m4 * m4 + m5 * m5) / 6) + self.floor_us

    @staticmethod
    def _cost(measured: list[float], model: list[float]) -> float:
        """Summed squared conductance misfit (the batch path's ``cost``): six sensors, in order."""
        m0, m1, m2, m3, m4, m5 = measured
        c0, c1, c2, c3, c4, c5 = model
        r0, r1, r2, r3, r4, r5 = m0 - c0, m1 - c1, m2 - c2, m3 - c3, m4 - c4, m5 - c5
        return r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3 + r4 * r4 + r5 * r5

    def misfit(self, measured: list[float], model: list[float]) -> float:
        """Relative RMS misfit (:meth:`OnePressCheck._misfit`)."""
        return math.sqrt(self._cost(measured, model) / len(measured)) / self._scale(measured)

    # ---- the check ------------------------------------------------------------------------------

    def refined_misfit(
        self,
        measured: list[float],
        params: list[float],
        stop_below: float,
        base: list[float] | None = None,
        sums: tuple[float, ...] | None = None,
    ) -> float:
        """:meth:`OnePressCheck._refined_misfit` for one frame (``base``: the model at ``params``
        and ``sums`` its normal equations, when the caller has them).

        The normal equations of the analytic Jacobian (:meth:`model_and_normal_equations`), summed
        in one pass over the sensors in the order the batch path's sums take, are kept after a
        failed step (the point did not move: only the damping changes)."""
        n, scale_m = len(measured), self._scale(measured)
        conductance_at, column_of, normal_equations = self.conductance_at, self.column, self.model_and_normal_equations
        x, y, f = params
        column = column_of(f)
        if base is None:
            base, sums = normal_equations(x, y, f, column, measured)
        cost = self._cost(measured, base)
        damping = 1e-3
        lx, ly, lf = _STEP_LIMIT
        moved = sums is None  # the normal equations at the point are still to be summed
        for _ in range(self.steps):
            if math.sqrt(cost / n) / scale_m <= stop_below:
                break
            if moved or sums is None:
                _, sums = normal_equations(x, y, f, column, measured)
                moved = False
            a00, a01, a02, a11, a12, a22, r0, r1, r2 = sums
            ridge = damping * (a00 + a11 + a22 + 1e-12)
            sx, sy, sf = _solve_spd3(a00 + ridge, a01, a02, a11 + ridge, a12, a22 + ridge, r0, r1, r2)
            cx = x + (-lx if sx < -lx else lx if sx > lx else sx)
            cy = y + (-ly if sy < -ly else ly if sy > ly else sy)
            cf = f + (-lf if sf < -lf else lf if sf > lf else sf)
            trial_column = column_of(cf)
            trial = conductance_at(cx, cy, trial_column)
            trial_cost = self._cost(measured, trial)
            if trial_cost < cost:
                x, y, f, column, base, cost, damping = cx, cy, cf, trial_column, trial, trial_cost, damping / 3.0
                moved = True
            else:
                damping *= 5.0
        return math.sqrt(cost / n) / scale_m

    def p_one_press(self, codes: list[float], estimate: list[float], screen: list[float] | None = None) -> float:
        """The flag of one frame (:meth:`OnePressCheck.p_one_press`): ``codes`` its six nominal-film
        readings, ``estimate`` its first five columns (cheapest first, as the batch path);
        ``screen``: a better point (x, y, force; float32 values) tried as it is first."""
        if not estimate[3] > 0.5:
            return 0.0
        if not estimate[4] > 0.5:
            return 0.5
        point = None if screen is None else (float(screen[0]), float(screen[1]), float(screen[2]))
        return self.flag_inside(self.measured(codes), float(estimate[0]), float(estimate[1]), float(estimate[2]), point)

    def flag_inside(
        self, measured: list[float], x: float, y: float, force: float, screen: Sequence[float] | None = None
    ) -> float:
        """:meth:`p_one_press` of a contact detected inside a triangle at ``x, y`` with ``force``
        (floats of float32 values; ``screen`` likewise), from the frame's :meth:`measured`
        conductances: the screen's point as it is (when given, as the batch path), else the
        estimate as it is, then :meth:`flag_refined`."""
        scale = self._scale(measured)
        if self.passes_at(measured, scale, *(screen if screen is not None else (x, y, force))):
            return 1.0
        return self.flag_refined(measured, scale, x, y, force, screen is not None)

    def passes_at(self, measured: list[float], scale: float, x: float, y: float, force: float) -> bool:
        """Whether the press at ``x, y`` with ``force`` (floats of float32 values) fits the frame's
        :meth:`measured` conductances as it is (``scale``: their :meth:`_scale`): :meth:`misfit`
        at most the threshold, with :func:`_log_force` written out."""
        floor = _FORCE_FLOOR
        model = self.conductance_at(x, y, self.column(math.log(floor if floor > force else force)))
        return math.sqrt(self._cost(measured, model) / 6) / scale <= self.threshold

    def flag_refined(
        self, measured: list[float], scale: float, x: float, y: float, force: float, screened: bool
    ) -> float:
        """The flag of a press whose first point as it is did not fit (``screened``: that was the
        screen's point, and the estimate at ``x, y, force`` is still to be tried as it is; else it
        was the estimate): the refinements from the estimate, then from the sensors'
        conductance-weighted centroid. ``scale``: the :meth:`measured` conductances' :meth:`_scale`."""
        threshold = self.threshold
        start = [x, y, _log_force(force)]
        base = sums = None
        if screened:  # the half-space kernel's estimate, which hardly ever fits as it is: its sums at once
            base, sums = self.model_and_normal_equations(x, y, start[2], self.column(start[2]), measured)
            if math.sqrt(self._cost(measured, base) / 6) / scale <= threshold:
                return 1.0
        if self.refined_misfit(measured, start, threshold, base, sums) <= threshold:
            return 1.0
        weights = [max(m - self.leak, 0.0) + 1e-12 for m in measured]
        total = sum(weights)
        cx = sum(w * p[0] for w, p in zip(weights, self.positions, strict=True)) / total
        cy = sum(w * p[1] for w, p in zip(weights, self.positions, strict=True)) / total
        return 1.0 if self.refined_misfit(measured, [cx, cy, start[2]], threshold) <= threshold else 0.0
