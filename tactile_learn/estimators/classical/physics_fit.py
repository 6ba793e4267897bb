"""Physics fit: least squares of the contact model to each curve, then the nearest material.

Per curve (one pixel's window, degC), with the sensor's heat capacity ``C`` and loss ``G`` known
(the scene's mid-range values, or per-curve values: the oracle passes the truth):

1. Onset alignment and initial values from the library curve matching
   (:mod:`~tactile_learn.estimators.classical.curve_match`): baseline, onset, and the best
   template's effusivity, conductance, contact radius and amplitude.
2. Levenberg-Marquardt (vectorised over the batch, each curve with its own damping) of
   ``x(t) = b - V0 f(t - t0; e, H, k_s)``, ``f = 1 - v / V0`` the model of
   :class:`synth.sensors.thermal.ContactModel` (with ``S = 0``: a sensor at its steady state), in
   the parameters ``b, V0, log e, log H, log k_s, t0``. The nuisances' ranges are known from the
   scene and enter as flat priors with soft edges: ``V0`` within ``[Q/G - offset_max,
   Q/G - offset_min]`` (0.25 K edges) and ``log H`` within the scene's conductance range (0.3);
   ``log k_s`` has a Gaussian prior (s.d. 1.5) around its initial value. Residuals are weighted by
   the curve's noise. (The same damped Gauss-Newton as ``scipy.optimize.least_squares``'s 'lm',
   written batched so that thousands of curves fit in one vectorised loop.) Each iteration makes
   one model call: the trial point and its forward-difference neighbours together (an accepted
   trial's Jacobian is the next iteration's; after a rejected one the normal equations are kept),
   so that at batch 1 numpy's per-call cost stays a few times the arithmetic, not 15x. Every
   curve's iterations are its own: batch 1 gives the batch's answers to the bit.
3. Classification: the fit's covariance gives ``log e`` and, through ``k_s = 4 k / (pi a)``,
   ``log alpha = 2 log(pi a k_s / (4 e))`` with the contact radius ``a`` unknown within the scene's
   range (its log-uniform variance is added). Each material is a Gaussian in (``log e``,
   ``log alpha``) whose s.d. is its property spread (uniform half-width / sqrt 3); the score is the
   Gaussian log-likelihood of the fitted pair under fit covariance + material spread, so the
   diffusivity counts exactly as much as it is identified (for short contacts or polymers barely
   at all). Probabilities are the softmax of the scores; a curve without a detected onset is
   ``none``.

The calibration of the sensor itself from touches of known materials (the same contact model) is
:func:`tactile_learn.calibration.thermal_seed.calibrate_sensor`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import special

from synth.materials import Material
from synth.scene import Scene
from synth.sensors.thermal import ContactModel, ThermalConfig, spreading_conductance
from synth.sensors.thermal.fast import _g_series
from synth.sensors.thermal.physics import _SERIES_RADIUS
from tactile_learn.estimators.base import Classifier
from tactile_learn.estimators.classical.curve_match import (
    CurveMatchEstimator,
    heated,
    merge_classes,
    nominal_sensor,
    softmax,
)
from tactile_learn.estimators.classical.physics_fit_one_frame import fit_one_curve, one_curve_start
from tactile_learn.thermal_frame import detect_onset_one
from tactile_learn.validation.thermal import thermal_check

__all__ = ["CurveFit", "PhysicsFitEstimator", "contact_drop", "fit_curves", "material_gaussians", "material_scores"]

_BOUNDS = np.array(
    [
        [-np.inf, np.inf],  # b (degC)
        [-np.inf, np.inf],  # V0 (K)
        [math.log(5.0), math.log(1e5)],  # log e
        [math.log(30.0), math.log(1e7)],  # log H
        [math.log(0.01), math.log(1e7)],  # log k_s
        [-np.inf, np.inf],  # t0 (s), bounded per curve to the window
    ]
)
_STEPS = np.array([0.0, 0.0, 1e-4, 1e-4, 1e-4, 0.0])  # forward-difference steps (log parameters)


def contact_drop(
    t_rel: np.ndarray, c: np.ndarray, g: np.ndarray, e: np.ndarray, h: np.ndarray, ks: np.ndarray
) -> np.ndarray:
    """Normalised drop ``f = 1 - v/V0`` (B, W) at times ``t_rel`` (B, W) after onset (0 before);
    the model is evaluated only where ``t_rel > 0``."""
    model = ContactModel.create(c, g, h, e, ks, 1.0, 0.0)
    after = t_rel > 0
    out = np.zeros(t_rel.shape)
    rows, _ = np.nonzero(after)
    out[after] = 1.0 - model.excess_pairs(rows, t_rel[after])
    return out


def _drop_fast(
    t_rel: np.ndarray, c: np.ndarray, g: np.ndarray, e: np.ndarray, h: np.ndarray, ks: np.ndarray
) -> np.ndarray:
    """:func:`contact_drop`, the same numbers, for the fit's own parameters (finite and positive:
    clipped to ``_BOUNDS``): no checks, and ``g``'s power series only on the samples that take it
    (:func:`~synth.sensors.thermal.phi` evaluates it on every sample and keeps it on the few with
    ``|y| < 0.1``)."""
    ones = np.ones_like(c)
    r, w = ContactModel(c, g, h, e, ks, ones, 0.0 * ones).poles
    after = t_rel > 0
    rows, _ = np.nonzero(after)
    root_t = np.sqrt(t_rel[after])[:, None]
    y = r[rows] * -root_t
    small = np.abs(y) < _SERIES_RADIUS
    y_safe = np.where(small, 1.0 + 0j, y)
    g_y = (1 - special.erfcx(y_safe)) / y_safe
    if small.any():
        g_y[small] = _g_series(y[small])
    out = np.zeros(t_rel.shape)
    out[after] = 1.0 - (1.0 + np.real((w[rows] * (root_t * g_y)).sum(axis=-1)))
    return out


@dataclass
class CurveFit:
    """Fitted parameters (B, 6) ``b, V0, log e, log H, log k_s, t0``, their covariance (B, 6, 6),
    the reduced chi-square (B,), and the onset detection (a curve without an onset is not fitted:
    its initial values, a zero covariance, a NaN chi-square)."""

    theta: np.ndarray
    cov: np.ndarray
    chi2: np.ndarray
    detected: np.ndarray


def fit_curves(
    x: np.ndarray,
    config: ThermalConfig,
    heat_capacity: np.ndarray,
    loss: np.ndarray,
    init: np.ndarray,
    sigma: np.ndarray,
    v0_range: np.ndarray,
    iterations: int = 25,
    fit_spreading: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Batched Levenberg-Marquardt of the model to curves ``x`` (B, W) from ``init`` (B, 6).

    ``v0_range`` (B, 2): the interval the scene allows for ``V0`` (a flat prior with soft 0.25 K
    edges); ``log H`` has the same kind of prior over the scene's conductance range (edges 0.3).

    Returns the parameters (B, 6), the covariance (B, 6, 6) (inverse of the weighted normal
    matrix, prior included, scaled by the reduced chi-square when it exceeds 1) and that reduced
    chi-square (B,).
    """
    x = np.asarray(x, dtype=np.float64)
    b, w = x.shape
    fs = config.readout.sampling_hz
    t = np.arange(w) / fs
    c = np.asarray(heat_capacity, dtype=np.float64).reshape(b)
    g = np.asarray(loss, dtype=np.float64).reshape(b)
    inv_sigma = 1.0 / np.asarray(sigma, dtype=np.float64).reshape(b, 1)  # sigma is floored > 0
    lh_lo, lh_hi = (math.log(v) for v in config.contact.conductance_w_m2k)
    v_lo, v_hi = np.asarray(v0_range, dtype=np.float64).reshape(b, 2).T
    edge_v, edge_h = 0.25, 0.3
    theta = np.array(init, dtype=np.float64)
    mu_k = theta[:, 4].copy()
    sd_k = 1.5
    lo = np.broadcast_to(_BOUNDS[:, 0], theta.shape).copy()
    hi = np.broadcast_to(_BOUNDS[:, 1], theta.shape).copy()
    lo[:, 5], hi[:, 5] = -1.0 / fs, (w - 1) / fs
    if not fit_spreading:
        lo[:, 4], hi[:, 4] = theta[:, 4], theta[:, 4]
    active = np.array([True, True, True, True, fit_spreading, True])

    free = [j for j in (2, 3, 4, 5) if active[j]]  # parameters with forward differences
    steps = [_STEPS[j] if j != 5 else 0.02 / fs for j in free]
    c_all, g_all = np.tile(c, 1 + len(free)), np.tile(g, 1 + len(free))

    def evaluate(th: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The model ``b - V0 f`` (B, W), ``f`` and the forward-difference columns (J, B, W) of
        the residuals at ``th``: the point and its J neighbours in one model call (a call per
        neighbour cost ~5x the arithmetic at batch 1)."""
        moved = np.repeat(th[None], 1 + len(free), axis=0)
        for i, (j, step) in enumerate(zip(free, steps, strict=True)):
            moved[1 + i, :, j] += step
        flat_th = moved.reshape(-1, 6)
        f_all = _drop_fast(
            t[None, :] - flat_th[:, 5:6],
            c_all,
            g_all,
            np.exp(flat_th[:, 2]),
            np.exp(flat_th[:, 3]),
            np.exp(flat_th[:, 4]),
        ).reshape(1 + len(free), b, w)
        pred_all = moved[:, :, :1] - moved[:, :, 1:2] * f_all
        pred = pred_all[0]
        columns = np.empty((len(free), b, w))
        for i, step in enumerate(steps):
            columns[i] = -(pred_all[1 + i] - pred) * inv_sigma / step
        return pred, f_all[0], columns

    def flat(v: np.ndarray, lo_: np.ndarray | float, hi_: np.ndarray | float, edge: float) -> np.ndarray:
        """Flat-bottom prior residual: ``(v - lo) / edge`` below, ``(v - hi) / edge`` above, 0 within."""
        return (v - np.minimum(np.maximum(v, lo_), hi_)) / edge

    def slope(v: np.ndarray, lo_: np.ndarray | float, hi_: np.ndarray | float, edge: float) -> np.ndarray:
        """The flat prior's derivative."""
        return np.where((v < lo_) | (v > hi_), 1.0 / edge, 0.0)

    def residuals(th: np.ndarray, pred: np.ndarray) -> np.ndarray:
        res = np.empty((b, w + 3))
        np.subtract(x, pred, out=res[:, :w])
        res[:, :w] *= inv_sigma
        res[:, w] = flat(th[:, 1], v_lo, v_hi, edge_v)
        res[:, w + 1] = flat(th[:, 3], lh_lo, lh_hi, edge_h)
        res[:, w + 2] = (th[:, 4] - mu_k) / sd_k
        return res

    def jacobian(th: np.ndarray, f: np.ndarray, columns: np.ndarray) -> np.ndarray:
        jac = np.zeros((b, w + 3, 6))
        jac[:, :w, 0] = -inv_sigma  # d residual / d b
        jac[:, :w, 1] = f * inv_sigma
        for i, j in enumerate(free):
            jac[:, :w, j] = columns[i]
        jac[:, w, 1] = slope(th[:, 1], v_lo, v_hi, edge_v)
        jac[:, w + 1, 3] = slope(th[:, 3], lh_lo, lh_hi, edge_h)
        jac[:, w + 2, 4] = 1.0 / sd_k
        return jac

    # the Jacobian's columns come with every evaluation (of a trial point too: an accepted trial's
    # are the next iteration's; a rejected one's are not needed, the point's are kept)
    pred, f, columns = evaluate(theta)
    res = residuals(theta, pred)
    cost = (res**2).sum(axis=1)
    lam = np.full(b, 1e-2)
    eye = np.eye(6)
    moved_any = True
    for _ in range(iterations):
        if moved_any:  # else every point, hence its normal equations, is the last iteration's
            jac = jacobian(theta, f, columns)
            jtj = np.einsum("bki,bkj->bij", jac, jac)
            jtr = np.where(active, np.einsum("bki,bk->bi", jac, res), 0.0)[..., None]
            diag = np.einsum("bii->bi", jtj)[:, :, None] * eye + 1e-9 * eye
        damp = jtj + lam[:, None, None] * diag
        damp[:, ~active, :] = 0.0
        damp[:, :, ~active] = 0.0
        damp[:, ~active, ~active] = 1.0
        step = -np.linalg.solve(damp, jtr)[..., 0]
        trial = np.clip(theta + step, lo, hi)
        pred_t, f_t, columns_t = evaluate(trial)
        res_t = residuals(trial, pred_t)
        cost_t = (res_t**2).sum(axis=1)
        better = np.isfinite(cost_t) & (cost_t < cost)
        moved_any = bool(better.any())
        if moved_any:
            theta = np.where(better[:, None], trial, theta)
            pred = np.where(better[:, None], pred_t, pred)
            f = np.where(better[:, None], f_t, f)
            columns = np.where(better[None, :, None], columns_t, columns)
            res = np.where(better[:, None], res_t, res)
            cost = np.where(better, cost_t, cost)
        lam = np.clip(np.where(better, lam / 3.0, lam * 4.0), 1e-9, 1e9)
    jac = jacobian(theta, f, columns)
    jtj = np.einsum("bki,bkj->bij", jac, jac)
    jtj[:, ~active, :] = 0.0
    jtj[:, :, ~active] = 0.0
    jtj[:, ~active, ~active] = 1.0
    chi2 = ((res[:, :w]) ** 2).sum(axis=1) / max(w - 6, 1)
    cov = np.linalg.pinv(jtj) * np.maximum(chi2, 1.0)[:, None, None]
    return theta, cov, chi2


def _log_range(lo: float, hi: float) -> tuple[float, float]:
    """Centre and s.d. (uniform half-width / sqrt 3) of a log-interval."""
    return 0.5 * (math.log(lo) + math.log(hi)), 0.5 * (math.log(hi) - math.log(lo)) / math.sqrt(3.0)


def material_gaussians(materials: Sequence[Material]) -> np.ndarray:
    """(K, 4): mean and s.d. of log e and log alpha of each material over its property spread."""
    rows = []
    for m in materials:
        sk, sr, sc = m.spread
        e_lo = math.sqrt(m.k_w_mk * (1 - sk) * m.rho_kg_m3 * (1 - sr) * m.c_j_kgk * (1 - sc))
        e_hi = math.sqrt(m.k_w_mk * (1 + sk) * m.rho_kg_m3 * (1 + sr) * m.c_j_kgk * (1 + sc))
        a_lo = m.k_w_mk * (1 - sk) / (m.rho_kg_m3 * (1 + sr) * m.c_j_kgk * (1 + sc))
        a_hi = m.k_w_mk * (1 + sk) / (m.rho_kg_m3 * (1 - sr) * m.c_j_kgk * (1 - sc))
        me, se = _log_range(e_lo, e_hi)
        ma, sa = _log_range(a_lo, a_hi)
        # effusivity spreads below 1 % would make the score needlessly sharp
        rows.append([me, max(se, 0.01), ma, max(sa, 0.02)])
    return np.array(rows)


def material_scores(
    theta: np.ndarray,
    cov: np.ndarray,
    config: ThermalConfig,
    use_diffusivity: bool = True,
    gaussians: np.ndarray | None = None,
) -> np.ndarray:
    """Log-scores (B, K) of every material for fitted parameters (see the module docstring);
    ``gaussians``: :func:`material_gaussians` of the scene's materials, when already computed."""
    gauss = material_gaussians(config.material_list) if gaussians is None else gaussians
    le = theta[:, 2]
    var_e = cov[:, 2, 2]
    d_e = le[:, None] - gauss[None, :, 0]
    if not (use_diffusivity and config.contact.spreading):
        v = var_e[:, None] + gauss[None, :, 1] ** 2
        return -0.5 * d_e**2 / v - 0.5 * np.log(v)  # v >= 1e-4: material s.d. floored
    r_lo, r_hi = config.contact.radius_mm
    log_a, sd_a = _log_range(r_lo * 1e-3, r_hi * 1e-3)
    la = 2.0 * (math.log(math.pi / 4.0) + log_a + theta[:, 4] - le)
    var_a = 4.0 * (cov[:, 4, 4] + var_e - 2.0 * cov[:, 2, 4]) + 4.0 * sd_a**2
    cov_ea = 2.0 * (cov[:, 2, 4] - var_e)  # cov(le, 2 (lk - le))
    d_a = la[:, None] - gauss[None, :, 2]
    s_ee = var_e[:, None] + gauss[None, :, 1] ** 2
    s_aa = var_a[:, None] + gauss[None, :, 3] ** 2
    s_ea = np.broadcast_to(cov_ea[:, None], s_ee.shape)
    det = np.maximum(s_ee * s_aa - s_ea**2, 1e-300)  # positive definite; guard round-off
    quad = (s_aa * d_e**2 - 2 * s_ea * d_e * d_a + s_ee * d_a**2) / det
    return -0.5 * quad - 0.5 * np.log(det)


class PhysicsFitEstimator(Classifier):
    """Least-squares fit of the contact model, then the nearest material (see the module docstring).

    ``heat_capacity`` / ``loss`` / ``heater``: the sensor's, per curve (arrays as long as the input)
    or scalars; ``None`` takes the scene's mid-range values (the heater's and loss's ranges then set
    the allowed ``V0 = Q/G - offset``). The oracle passes each curve's true values.
    """

    task = "thermal"
    name = "physics_fit"

    def __init__(
        self,
        scene: Scene,
        heat_capacity: float | np.ndarray | None = None,
        loss: float | np.ndarray | None = None,
        heater: float | np.ndarray | None = None,
        iterations: int = 25,
        use_diffusivity: bool = True,
        chunk: int = 512,
    ) -> None:
        self.scene = scene
        self.heat_capacity = heat_capacity
        self.loss = loss
        self.heater = heater
        self.iterations = iterations
        self.use_diffusivity = use_diffusivity
        self.chunk = chunk

    def prepare(self) -> PhysicsFitEstimator:
        """Build the curve matcher that gives every fit its onset and initial values (once)."""
        if "matcher_" not in self.__dict__:
            cfg: ThermalConfig = self.scene.sensor
            self.input_check_ = thermal_check(cfg)
            self.matcher_ = CurveMatchEstimator(self.scene).prepare()
            # the materials' tables, read by every single-frame call
            self.materials_ = (
                np.array([m.effusivity for m in cfg.material_list]),
                np.array([m.k_w_mk for m in cfg.material_list]),
                material_gaussians(cfg.material_list),
            )
        return self

    def _sensor(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Heat capacity, loss (B,) and the allowed V0 interval (B, 2) of every curve."""
        cfg: ThermalConfig = self.scene.sensor
        c0, g0 = nominal_sensor(cfg)
        c = np.broadcast_to(
            np.asarray(c0 if self.heat_capacity is None else self.heat_capacity, dtype=np.float64), (n,)
        )
        g = np.broadcast_to(np.asarray(g0 if self.loss is None else self.loss, dtype=np.float64), (n,))
        off_lo, off_hi = cfg.objects.offset_k
        if self.heater is None or self.loss is None:
            q_lo, q_hi = cfg.sensor.heater_w_m2
            g_lo, g_hi = cfg.sensor.loss_w_m2k
            excess_lo, excess_hi = np.full(n, q_lo / g_hi), np.full(n, q_hi / g_lo)  # loss > 0 (validated)
        else:
            q = np.broadcast_to(np.asarray(self.heater, dtype=np.float64), (n,))
            excess_lo = excess_hi = q / g
        return c, g, np.stack([excess_lo - off_hi, excess_hi - off_lo], axis=1)

    def fit_batch(self, x: np.ndarray, c: np.ndarray, g: np.ndarray, v0_range: np.ndarray) -> CurveFit:
        """The fit of curves ``x`` (B, W) with sensor values ``c``, ``g`` (B,), ``V0`` in ``v0_range``."""
        cfg: ThermalConfig = self.scene.sensor
        fs = cfg.readout.sampling_hz
        matcher: CurveMatchEstimator = self.prepared_state("matcher_")
        _, onset, best = matcher.scores(x)
        lib = matcher.library_
        mats = cfg.material_list
        m = lib.material[best]
        e0 = np.array([mt.effusivity for mt in mats])[m]
        h0 = lib.conductance[best]
        ks0 = spreading_conductance(np.array([mt.k_w_mk for mt in mats])[m], lib.radius_m[best])
        if not cfg.contact.spreading:
            ks0 = np.full_like(ks0, 0.01)  # frozen: negligible beside any contact conductance
        t_on = (onset.index + 1 - lib.phase[best]) / fs
        # amplitude of the best template from the onset on (least squares, any sign)
        w = x.shape[1]
        tt = np.arange(w)[None, :] / fs - t_on[:, None]
        f0 = contact_drop(tt, c, g, e0, h0, np.where(cfg.contact.spreading, ks0, 0.0))
        dev = onset.baseline[:, None] - x
        v0 = (dev * f0).sum(axis=1) / np.maximum((f0 * f0).sum(axis=1), 1e-12)  # |f|^2 > 0 after onset
        init = np.stack([onset.baseline, v0, np.log(e0), np.log(h0), np.log(ks0), t_on], axis=1)
        init[:, 1] = np.clip(init[:, 1], v0_range[:, 0], v0_range[:, 1])
        # only curves with an onset are fitted (the others are none whatever their fit): the rest
        # keep their initial values, a zero covariance and a NaN chi-square
        theta, cov, chi2 = init, np.zeros((len(x), 6, 6)), np.full(len(x), np.nan)
        fitted = np.flatnonzero(onset.detected)
        if len(fitted):
            theta = init.copy()
            theta[fitted], cov[fitted], chi2[fitted] = fit_curves(
                x[fitted], cfg, c[fitted], g[fitted], init[fitted], onset.sigma[fitted], v0_range[fitted],
                self.iterations, fit_spreading=cfg.contact.spreading,
            )  # fmt: skip
        return CurveFit(theta, cov, chi2, onset.detected)

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        return self.predict_proba_checked(self.prepared_state("input_check_")(X))

    def predict_proba_checked(self, x: np.ndarray) -> np.ndarray:
        self.prepared_state("matcher_")  # an unprepared estimator fails before any work
        x = heated(x).astype(np.float64)
        if len(x) == 1:
            return self._predict_one(x[0])
        k = len(self.scene.sensor.material_list)
        c, g, v0_range = self._sensor(len(x))
        out = np.zeros((len(x), k + 1), dtype=np.float32)
        for start in range(0, len(x), self.chunk):
            sl = slice(start, start + self.chunk)
            fit = self.fit_batch(x[sl], c[sl], g[sl], v0_range[sl])
            scores = material_scores(fit.theta, fit.cov, self.scene.sensor, self.use_diffusivity)
            scores = np.concatenate([scores, np.full((len(scores), 1), -np.inf)], axis=1)
            scores[~fit.detected] = -np.inf
            scores[~fit.detected, -1] = 0.0
            out[sl] = softmax(scores)
        return merge_classes(out, self.scene.sensor)

    def _predict_one(self, x: np.ndarray) -> np.ndarray:
        """:meth:`predict_proba_checked` of one curve ``x`` (W,): the batch path's steps in their
        one-curve forms (:mod:`~tactile_learn.estimators.classical.physics_fit_one_frame`)."""
        cfg: ThermalConfig = self.scene.sensor
        matcher: CurveMatchEstimator = self.prepared_state("matcher_")
        effusivity, conductivity, gaussians = self.prepared_state("materials_")
        scores = np.full((1, len(effusivity) + 1), -np.inf)
        onset = detect_onset_one(x, cfg.readout.sampling_hz, cfg.readout.adc_step_k)
        if not onset.detected:  # none (the batch path does not fit it either)
            scores[0, -1] = 0.0
        else:
            c, g, v0_range = self._sensor(1)
            lo_v, hi_v = float(v0_range[0, 0]), float(v0_range[0, 1])
            cap, loss = float(c[0]), float(g[0])
            init = one_curve_start(x, onset, cfg, matcher.library_, effusivity, conductivity, cap, loss, (lo_v, hi_v))
            theta, cov, _ = fit_one_curve(
                x, cfg, cap, loss, init, onset.sigma, (lo_v, hi_v), self.iterations, cfg.contact.spreading,
                _BOUNDS, _STEPS,
            )  # fmt: skip
            scores[:, :-1] = material_scores(theta[None], cov[None], cfg, self.use_diffusivity, gaussians)
        return merge_classes(softmax(scores).astype(np.float32), cfg)
