"""The physics fit's Levenberg-Marquardt for ONE curve: the batch-1 fast path.

:func:`~tactile_learn.estimators.classical.physics_fit.fit_curves` is written for batches: every
step is a numpy call over the whole batch, and at batch 1 each of its ~300 calls an iteration costs
more than its arithmetic (10 ms a fit against 2 ms per curve at batch 1024). This is the same
algorithm (the same model, priors, forward differences, damping schedule and iteration count) for
one curve, with the per-call costs taken out:

- the cubic's roots and weights of the trial point and its forward-difference neighbours in
  Python scalars (the batch path's closed form: ~40 numpy calls on 5 rows; the onset's neighbour
  shares the point's, a complex pair is solved once);
- the model only from the first sample after the onset, a real root by the real ``erfcx`` and a
  conjugate pair by one complex ``erfcx``, ``g``'s power series only where the direct form would
  lose digits (see :func:`_drops`);
- the accept/reject, damping and prior terms as Python branches and floats, the normal equations
  as ``J^T J`` (one product), the step by LAPACK's ``dgesv``;
- the onset, the best template and the initial amplitude by the one-curve helpers of
  :mod:`tactile_learn.thermal_frame`; a curve without an onset is ``none`` without a fit.

The model's numbers are the batch path's to ~1e-12 (a complex product or ``exp`` in Python and
in numpy's SIMD loops differ in the last bit; the conjugate pair and the direct form near the
onset, see :func:`_drops`). Where the fit converges that stays at rounding: probabilities within
3e-7 of the batch's on 320 held-out curves of the seed scene (tests: 1e-6). A fit that has not
converged after its iterations (a curve the model does not describe: reduced chi-square in the
hundreds) follows a path that rounding can steer: up to 1e-3 there (1 of 20 robot-scene curves),
where more iterations change the batch's own answer by far more.
"""

from __future__ import annotations

import cmath
import math
from typing import NamedTuple

import numpy as np
from scipy import special
from scipy.linalg import lapack

from synth.sensors.thermal import ContactModel, ThermalConfig
from synth.sensors.thermal.physics import _G_SERIES, _SERIES_RADIUS
from tactile_learn.estimators.classical.curve_match import CurveLibrary
from tactile_learn.thermal_frame import CurveOnset, drop_segment_one

__all__ = ["fit_one_curve", "one_curve_poles", "one_curve_start"]

#: the series' coefficients from y^1 on (its constant term added separately), complex for the product
_SERIES_TAIL = _G_SERIES[1:].astype(np.complex128)


def _direct_roots(a1: float, a2: float, a3: float) -> tuple[float, complex | float, complex | float] | None:
    """The roots of ``q^3 + a1 q^2 + a2 q + a3`` (``a3 != 0``) by the closed form of
    :func:`synth.sensors.thermal.physics._direct_roots` (one real root, the other two by Vieta's
    relations in the form that does not cancel); None where it breaks down (the caller then takes
    the batch path's solver). A complex pair is returned as its upper root twice (the caller
    conjugates the second)."""
    shift = a1 / 3.0
    pp = a2 - a1 * shift
    qq = a3 - shift * a2 + 2.0 * shift**3
    disc = (qq / 2.0) ** 2 + (pp / 3.0) ** 3
    if disc > 0:
        big = -math.copysign(math.cbrt(abs(qq) / 2.0 + math.sqrt(disc)), qq)
        if big == 0:
            return None
        t_one = big - pp / (3.0 * big)
    else:  # three real roots: the largest by the trigonometric form
        m = 2.0 * math.sqrt(max(-pp, 0.0) / 3.0)
        if m == 0 or pp == 0:
            return None
        t_one = m * math.cos(math.acos(min(max(3.0 * qq / (pp * m), -1.0), 1.0)) / 3.0)
    r1 = t_one - shift
    if r1 == 0:
        return None
    prod = -a3 / r1
    total = -a1 - r1 if r1 * r1 < abs(prod) else (a2 - prod) / r1
    half = total / 2.0
    d = half * half - prod
    root_d = math.sqrt(abs(d))
    if d < 0:
        upper = complex(half, root_d)
        return r1, upper, upper
    far = half + math.copysign(root_d, half)
    if far == 0:
        return None
    return r1, far, prod / far


def _newton(r: complex | float, a1: float, a2: float, a3: float) -> complex | float | None:
    """Two Newton steps on ``q^3 + a1 q^2 + a2 q + a3`` from ``r`` (the batch path's polish: a
    root finder's error is relative to the largest root); None at a vanishing derivative."""
    for _ in range(2):
        df = (3 * r + 2 * a1) * r + a2
        if df == 0:
            return None
        r = r - (((r + a1) * r + a2) * r + a3) / df
    return r


def one_curve_poles(
    c: float, g: float, h: float, e: float, ks: float
) -> tuple[tuple[complex, complex, complex], tuple[complex, complex, complex], bool] | None:
    """Roots and weights ``N(p) / D'(p)`` (``V0 = 1``, ``S = 0``) of
    :attr:`synth.sensors.thermal.ContactModel.poles` for one parameter set, in Python scalars, and
    whether they are a real root and a conjugate pair (first, then upper, then lower); None
    where the closed form fails its check, a root is 0, or two roots lie within the relative gap
    the batch path splits by nudging ``H`` (the caller then takes
    :class:`~synth.sensors.thermal.ContactModel`)."""
    c3, c2, c1 = c * e, c * (h + ks), e * (g + h)
    a1, a2, a3 = c2 / c3, c1 / c3, (g * (h + ks) + h * ks) / c3
    roots = _direct_roots(a1, a2, a3)
    if roots is None:
        return None
    pair = roots[1] is roots[2]
    p1, p2 = _newton(roots[0], a1, a2, a3), _newton(roots[1], a1, a2, a3)
    if p1 is None or p2 is None:
        return None
    # a complex pair stays conjugate under Newton's steps on real coefficients
    p3 = p2.conjugate() if pair else _newton(roots[2], a1, a2, a3)
    if p3 is None:
        return None
    m1, m2, m3 = abs(p1), abs(p2), abs(p3)
    if not (
        cmath.isfinite(p1 + p2 + p3)
        and abs(p1 + p2 + p3 + a1) <= 1e-9 * (m1 + m2 + m3)
        and abs(p1 * p2 * p3 + a3) <= 1e-9 * m1 * m2 * m3
        and abs(p1 - p2) >= 1e-3 * max(m1, m2)
        and abs(p1 - p3) >= 1e-3 * max(m1, m3)
        and abs(p2 - p3) >= 1e-3 * max(m2, m3)
        and m1 * m2 * m3 > 0
    ):
        return None
    w1 = -h * (e * p1 + ks) / ((3 * c3 * p1 + 2 * c2) * p1 + c1)
    w2 = -h * (e * p2 + ks) / ((3 * c3 * p2 + 2 * c2) * p2 + c1)
    w3 = w2.conjugate() if pair else -h * (e * p3 + ks) / ((3 * c3 * p3 + 2 * c2) * p3 + c1)
    return (complex(p1), complex(p2), complex(p3)), (complex(w1), complex(w2), complex(w3)), pair


#: largest |w / p| for which the terms skip g's series (see _drops)
_DIRECT_MAX = 1e3


class Poles(NamedTuple):
    """Roots, weights and weights over roots (P, 3) of parameter sets; whether every set is a
    real root (first) and a conjugate pair (upper, lower); whether some ``|w / p|`` exceeds
    ``_DIRECT_MAX`` (or ``p = 0``): then the terms near the onset take ``g``'s series."""

    roots: np.ndarray
    weights: np.ndarray
    over: np.ndarray
    pairs: bool
    series: bool = True


def _poles(c: float, g: float, params: list[list[float]], repeat_first: bool = False) -> Poles:
    """The poles of every parameter set ``(e, H, k_s)`` of ``params`` (and the first set's once
    more, last, with ``repeat_first``; a weight over a root at 0 is 0: that root's terms are all
    series, see :func:`_drops`)."""
    roots, weights, over = [], [], []
    pairs, series = True, False
    for e, h, ks in params:
        found = one_curve_poles(c, g, h, e, ks)
        if found is None:  # a near-double root or a failed closed form: the batch path's solver
            r, w = ContactModel.create(c, g, h, e, ks, 1.0, 0.0).poles
            found = (tuple(r.tolist()), tuple(w.tolist()), False)
        ps, ws, pair = found
        pairs = pairs and pair
        roots.append(ps)
        weights.append(ws)
        ratios = [w / p if p != 0 else 0j for p, w in zip(ps, ws, strict=True)]
        series = series or 0 in ps or max(abs(r) for r in ratios) > _DIRECT_MAX
        over.append(ratios)
    if repeat_first:
        roots.append(roots[0])
        weights.append(weights[0])
        over.append(over[0])
    return Poles(np.array(roots), np.array(weights), np.array(over), pairs, series)


def _series(y: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """``g(y)`` by its power series from its coefficients from ``y^1`` on (the powers by one
    cumulative product)."""
    powers = np.cumprod(np.repeat(y[:, None], len(coefficients), axis=1), axis=1)
    return powers @ coefficients + _G_SERIES[0]


def _drops(
    fs: float,
    t: np.ndarray,
    t0: np.ndarray,
    roots: np.ndarray,
    weights: np.ndarray,
    over: np.ndarray,
    pairs: bool,
    series: bool = True,
) -> np.ndarray:
    """Normalised drops ``f`` (P, W) of the parameter sets with roots, weights and weights over
    roots (P, 3) and onsets ``t0`` (P,), at times ``t = arange(W) / fs``: 0 up to the onset (the
    batch path's ``_drop_fast``).

    A root's term ``w sqrt(t) g(y)``, ``y = -p sqrt(t)``, is ``(erfcx(y) - 1) w / p`` (no division
    per sample), and ``sqrt(t) g(y) w`` by ``g``'s power series where ``|y| < 0.1`` when ``series``:
    near the onset ``erfcx(y) - 1`` cancels, to an absolute error ~``eps |w / p|`` in the term
    (the batch path's quotient: the same), below 1e-12 of ``V0`` for ``|w / p| <= _DIRECT_MAX``,
    where the series is left out (its gathers were a third of the calls). With ``pairs`` (a real
    root and a conjugate pair in every set) the real root takes the real ``erfcx`` and the pair
    one complex evaluation: ``erfcx`` of the conjugate is the conjugate, so the pair's real part
    is twice the upper root's (the complex ``erfcx``, ~5x the real one, is most of the model's
    arithmetic)."""
    n_sets, w = len(t0), len(t)
    out = np.zeros((n_sets, w))
    # the samples before the earliest onset are 0 in every set: the model from one sample before
    # the first after it (rounding of t0 fs); a sample at or before a set's own onset gives 0 below
    first = min(max(math.floor(float(t0.min()) * fs) - 1, 0), w)
    root_t = np.sqrt(np.maximum(t[first:] - t0[:, None], 0.0))  # 0 up to each set's own onset
    if pairs:
        y_real = root_t * -roots[:, :1].real  # (P, W')
        y_pair = root_t * -roots[:, 1:2]
        total = (special.erfcx(y_real) - 1) * over[:, :1].real
        pair = (special.erfcx(y_pair) - 1) * over[:, 1:2]
        for y, terms, column in ((y_real, total, 0), (y_pair, pair, 1)) if series else ():
            i, k = np.nonzero(np.abs(y) < _SERIES_RADIUS)  # every sample up to the onset (y = 0) too
            tail = _SERIES_TAIL.real if column == 0 else _SERIES_TAIL
            scale = weights[i, column] * root_t[i, k]
            terms[i, k] = _series(y[i, k], tail) * (scale.real if column == 0 else scale)
        total += 2.0 * pair.real
    else:
        y3 = roots[:, None, :] * -root_t[:, :, None]  # (P, W', 3)
        terms3 = (special.erfcx(y3) - 1) * over[:, None, :]
        if series:
            i, k, j = np.nonzero(np.abs(y3) < _SERIES_RADIUS)
            terms3[i, k, j] = _series(y3[i, k, j], _SERIES_TAIL) * (weights[i, j] * root_t[i, k])
        real = terms3.real
        total = real[..., 0] + real[..., 1] + real[..., 2]
    out[:, first:] = 1.0 - (1.0 + total)
    return out


def one_curve_start(
    x: np.ndarray,
    onset: CurveOnset,
    config: ThermalConfig,
    library: CurveLibrary,
    material_effusivity: np.ndarray,
    material_k: np.ndarray,
    heat_capacity: float,
    loss: float,
    v0_range: tuple[float, float],
) -> np.ndarray:
    """The fit's initial values (6,) of one curve ``x`` (W,) with ``onset``
    (:func:`~tactile_learn.thermal_frame.detect_onset_one`): the batch path's ``fit_batch`` set-up
    (curve matching's best template, the template's amplitude by least squares) with the
    one-curve matching. ``material_effusivity`` / ``material_k`` (K,): the scene's materials'
    properties."""
    fs = config.readout.sampling_hz
    y, n_valid = drop_segment_one(x, onset, library.lookback)
    # the best template (CurveLibrary.match's argmin) of the drop's valid span
    n = min(max(n_valid, 1), len(library.cum_sq_t))
    dots = np.maximum(y[:n] @ library.templates_t[:n], 0.0)
    norms = library.cum_sq_t[n - 1]
    gain = np.divide(dots * dots, norms, out=np.zeros_like(dots), where=norms > 0)
    best = int(np.maximum(float(y @ y) - gain, 0.0).argmin())
    m = int(library.material[best])
    e0, h0 = float(material_effusivity[m]), float(library.conductance[best])
    spreading = config.contact.spreading
    # spreading_conductance 4 k / (pi a); frozen at a value negligible beside any conductance
    ks0 = 4.0 * float(material_k[m]) / (math.pi * float(library.radius_m[best])) if spreading else 0.01
    t_on = (onset.index + 1 - float(library.phase[best])) / fs
    f0 = _drops(
        fs,
        np.arange(len(x)) / fs,
        np.array([t_on]),
        *_poles(heat_capacity, loss, [[e0, h0, ks0 if spreading else 0.0]]),
    )[0]
    v0 = float((onset.baseline - x) @ f0) / max(float(f0 @ f0), 1e-12)  # |f|^2 > 0 after onset
    v0 = min(max(v0, v0_range[0]), v0_range[1])
    return np.array([onset.baseline, v0, math.log(e0), math.log(h0), math.log(ks0), t_on])


def fit_one_curve(
    x: np.ndarray,
    config: ThermalConfig,
    heat_capacity: float,
    loss: float,
    init: np.ndarray,
    sigma: float,
    v0_range: tuple[float, float],
    iterations: int,
    fit_spreading: bool,
    bounds: np.ndarray,
    log_steps: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`~tactile_learn.estimators.classical.physics_fit.fit_curves` for one curve ``x`` (W,):
    the parameters (6,), their covariance (6, 6) and the reduced chi-square. ``bounds`` (6, 2)
    and ``log_steps`` (6,) are the batch path's parameter box and forward-difference steps."""
    x = np.asarray(x, dtype=np.float64)
    w = len(x)
    fs = config.readout.sampling_hz
    t = np.arange(w) / fs
    c, g = float(heat_capacity), float(loss)
    inv_sigma = 1.0 / float(sigma)
    lh_lo, lh_hi = (math.log(v) for v in config.contact.conductance_w_m2k)
    v_lo, v_hi = (float(v) for v in v0_range)
    edge_v, edge_h, sd_k = 0.25, 0.3, 1.5
    theta = np.array(init, dtype=np.float64).reshape(6)
    mu_k = float(theta[4])
    lo, hi = bounds[:, 0].copy(), bounds[:, 1].copy()
    lo[5], hi[5] = -1.0 / fs, (w - 1) / fs
    if not fit_spreading:
        lo[4] = hi[4] = theta[4]
    free = [j for j in (2, 3, 4, 5) if j != 4 or fit_spreading]
    steps = np.array([log_steps[j] if j != 5 else 0.02 / fs for j in free])
    # the trial point and its neighbours: row 0 the point, row 1 + i parameter free[i] moved
    shift = np.zeros((1 + len(free), 6))
    for i, (j, step) in enumerate(zip(free, steps, strict=True)):
        shift[1 + i, j] = step
    col_scale = -inv_sigma / steps[:, None]

    def evaluate(th: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The model (W,), ``f`` (W,) and the residuals' forward-difference columns (J, W) at ``th``."""
        moved = th + shift
        # the onset's neighbour (last) has the point's (e, H, k_s): its poles are the point's
        logs = np.exp(moved[:-1, 2:5]).tolist()
        f_all = _drops(fs, t, moved[:, 5], *_poles(c, g, logs, repeat_first=True))
        pred_all = th[0] - th[1] * f_all
        pred = pred_all[0]
        return pred, f_all[0], (pred_all[1:] - pred) * col_scale

    def residuals(th: np.ndarray, pred: np.ndarray) -> tuple[np.ndarray, float]:
        res = np.empty(w + 3)
        np.multiply(x - pred, inv_sigma, out=res[:w])
        v, lh = float(th[1]), float(th[3])
        res[w] = (v - min(max(v, v_lo), v_hi)) / edge_v  # the flat priors (see fit_curves)
        res[w + 1] = (lh - min(max(lh, lh_lo), lh_hi)) / edge_h
        res[w + 2] = (float(th[4]) - mu_k) / sd_k
        return res, float(res @ res)

    jac = np.zeros((w + 3, 6))
    jac[:w, 0] = -inv_sigma
    jac[w + 2, 4] = 1.0 / sd_k

    def jacobian(th: np.ndarray, f: np.ndarray, columns: np.ndarray) -> np.ndarray:
        np.multiply(f, inv_sigma, out=jac[:w, 1])
        jac[:w, free] = columns.T
        v, lh = float(th[1]), float(th[3])
        jac[w, 1] = 1.0 / edge_v if (v < v_lo or v > v_hi) else 0.0
        jac[w + 1, 3] = 1.0 / edge_h if (lh < lh_lo or lh > lh_hi) else 0.0
        return jac

    pred, f, columns = evaluate(theta)
    res, cost = residuals(theta, pred)
    lam = 1e-2
    inactive = 4 if not fit_spreading else None
    moved_any = True
    for _ in range(iterations):
        if moved_any:
            jac = jacobian(theta, f, columns)
            jtj = jac.T @ jac
            jtr = jac.T @ res
            if inactive is not None:
                jtr[inactive] = 0.0
            diag = np.diag(jtj.diagonal() + 1e-9)
        damp = jtj + lam * diag
        if inactive is not None:
            damp[inactive, :] = 0.0
            damp[:, inactive] = 0.0
            damp[inactive, inactive] = 1.0
        _, _, solved, info = lapack.dgesv(damp, jtr)  # LAPACK's solver without numpy's wrapping
        if info != 0:  # singular (damping makes it regular): numpy's error, as the batch path
            solved = np.linalg.solve(damp, jtr)
        trial = np.minimum(np.maximum(theta - solved, lo), hi)
        pred_t, f_t, columns_t = evaluate(trial)
        res_t, cost_t = residuals(trial, pred_t)
        moved_any = math.isfinite(cost_t) and cost_t < cost
        if moved_any:
            theta, pred, f, columns, res, cost = trial, pred_t, f_t, columns_t, res_t, cost_t
        lam = min(max(lam / 3.0 if moved_any else lam * 4.0, 1e-9), 1e9)
    jac = jacobian(theta, f, columns)
    jtj = jac.T @ jac
    if inactive is not None:
        jtj[inactive, :] = 0.0
        jtj[:, inactive] = 0.0
        jtj[inactive, inactive] = 1.0
    chi2 = float(res[:w] @ res[:w]) / max(w - 6, 1)
    cov = np.linalg.pinv(jtj) * max(chi2, 1.0)
    return theta, cov, chi2
