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
   written batched so that thousands of curves fit in one vectorised loop.)
3. Classification: the fit's covariance gives ``log e`` and, through ``k_s = 4 k / (pi a)``,
   ``log alpha = 2 log(pi a k_s / (4 e))`` with the contact radius ``a`` unknown within the scene's
   range (its log-uniform variance is added). Each material is a Gaussian in (``log e``,
   ``log alpha``) whose s.d. is its property spread (uniform half-width / sqrt 3); the score is the
   Gaussian log-likelihood of the fitted pair under fit covariance + material spread, so the
   diffusivity counts exactly as much as it is identified (for short contacts or polymers barely
   at all). Probabilities are the softmax of the scores; a curve without a detected onset is
   ``none``.

:func:`calibrate_sensor` fits the sensor itself (``C``, ``G``, the contact radius; each touch's
conductance, amplitude, onset and baseline) from touches of known materials with
``scipy.optimize.least_squares``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from synth.errors import DataError
from synth.materials import Material, get_material
from synth.scene import Scene
from synth.sensors.thermal import ContactModel, ThermalConfig, spreading_conductance
from tactile_learn.estimators.base import Estimator
from tactile_learn.estimators.classical.curve_match import (
    CurveMatchEstimator,
    detect_onset,
    heated_window,
    merge_classes,
    nominal_sensor,
    softmax,
)

if TYPE_CHECKING:
    from tactile_learn.thermal_recordings import Touch

__all__ = ["CurveFit", "PhysicsFitEstimator", "calibrate_sensor", "fit_curves", "material_scores"]

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


def _drop(t_rel: np.ndarray, c: np.ndarray, g: np.ndarray, e: np.ndarray, h: np.ndarray, ks: np.ndarray) -> np.ndarray:
    """Normalised drop ``f = 1 - v/V0`` (B, W) at times ``t_rel`` (B, W) after onset (0 before);
    the model is evaluated only where ``t_rel > 0``."""
    model = ContactModel.create(c, g, h, e, ks, 1.0, 0.0)
    after = t_rel > 0
    out = np.zeros(t_rel.shape)
    rows, _ = np.nonzero(after)
    out[after] = 1.0 - model.excess_pairs(rows, t_rel[after])
    return out


@dataclass
class CurveFit:
    """Fitted parameters (B, 6) ``b, V0, log e, log H, log k_s, t0``, their covariance (B, 6, 6),
    the reduced chi-square (B,), and the onset detection."""

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

    def model(th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        f = _drop(t[None, :] - th[:, 5:6], c, g, np.exp(th[:, 2]), np.exp(th[:, 3]), np.exp(th[:, 4]))
        return th[:, :1] - th[:, 1:2] * f, f

    def flat(
        v: np.ndarray, lo_: np.ndarray | float, hi_: np.ndarray | float, edge: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Flat-bottom prior residual and its derivative."""
        below, above = v < lo_, v > hi_
        r = (np.where(below, v - lo_, 0.0) + np.where(above, v - hi_, 0.0)) / edge
        return r, np.where(below | above, 1.0 / edge, 0.0)

    def residuals(th: np.ndarray, pred: np.ndarray) -> np.ndarray:
        data = (x - pred) * inv_sigma
        prior = np.stack(
            [flat(th[:, 1], v_lo, v_hi, edge_v)[0], flat(th[:, 3], lh_lo, lh_hi, edge_h)[0], (th[:, 4] - mu_k) / sd_k],
            axis=1,
        )
        return np.concatenate([data, prior], axis=1)

    def jacobian(th: np.ndarray, pred: np.ndarray, f: np.ndarray) -> np.ndarray:
        jac = np.zeros((b, w + 3, 6))
        jac[:, :w, 0] = -inv_sigma  # d residual / d b
        jac[:, :w, 1] = f * inv_sigma
        for j in (2, 3, 4, 5):
            if not active[j]:
                continue
            step = _STEPS[j] if j != 5 else 0.02 / fs
            moved = th.copy()
            moved[:, j] += step
            jac[:, :w, j] = -(model(moved)[0] - pred) * inv_sigma / step
        jac[:, w, 1] = flat(th[:, 1], v_lo, v_hi, edge_v)[1]
        jac[:, w + 1, 3] = flat(th[:, 3], lh_lo, lh_hi, edge_h)[1]
        jac[:, w + 2, 4] = 1.0 / sd_k
        return jac

    pred, f = model(theta)
    res = residuals(theta, pred)
    cost = (res**2).sum(axis=1)
    lam = np.full(b, 1e-2)
    eye = np.eye(6)
    for _ in range(iterations):
        jac = jacobian(theta, pred, f)
        jtj = np.einsum("bki,bkj->bij", jac, jac)
        jtr = np.einsum("bki,bk->bi", jac, res)
        diag = np.einsum("bii->bi", jtj)
        damp = jtj + lam[:, None, None] * (diag[:, :, None] * eye + 1e-9 * eye)
        damp[:, ~active, :] = 0.0
        damp[:, :, ~active] = 0.0
        damp[:, ~active, ~active] = 1.0
        step = -np.linalg.solve(damp, np.where(active, jtr, 0.0)[..., None])[..., 0]
        trial = np.clip(theta + step, lo, hi)
        pred_t, f_t = model(trial)
        res_t = residuals(trial, pred_t)
        cost_t = (res_t**2).sum(axis=1)
        better = np.isfinite(cost_t) & (cost_t < cost)
        theta = np.where(better[:, None], trial, theta)
        pred = np.where(better[:, None], pred_t, pred)
        f = np.where(better[:, None], f_t, f)
        res = np.where(better[:, None], res_t, res)
        cost = np.where(better, cost_t, cost)
        lam = np.clip(np.where(better, lam / 3.0, lam * 4.0), 1e-9, 1e9)
    jac = jacobian(theta, pred, f)
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


def _material_gaussians(materials: Sequence[Material]) -> np.ndarray:
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
    theta: np.ndarray, cov: np.ndarray, config: ThermalConfig, use_diffusivity: bool = True
) -> np.ndarray:
    """Log-scores (B, K) of every material for fitted parameters (see the module docstring)."""
    gauss = _material_gaussians(config.material_list)
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


class PhysicsFitEstimator(Estimator):
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

    @cached_property
    def matcher_(self) -> CurveMatchEstimator:
        return CurveMatchEstimator(self.scene)

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

    def fit(self, X: np.ndarray, y: Any = None) -> PhysicsFitEstimator:
        return self

    def fit_batch(self, x: np.ndarray, c: np.ndarray, g: np.ndarray, v0_range: np.ndarray) -> CurveFit:
        """The fit of curves ``x`` (B, W) with sensor values ``c``, ``g`` (B,), ``V0`` in ``v0_range``."""
        cfg: ThermalConfig = self.scene.sensor
        fs = cfg.readout.sampling_hz
        _, onset, best = self.matcher_.scores(x)
        lib = self.matcher_.library_
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
        f0 = _drop(tt, c, g, e0, h0, np.where(cfg.contact.spreading, ks0, 0.0))
        dev = onset.baseline[:, None] - x
        v0 = (dev * f0).sum(axis=1) / np.maximum((f0 * f0).sum(axis=1), 1e-12)  # |f|^2 > 0 after onset
        init = np.stack([onset.baseline, v0, np.log(e0), np.log(h0), np.log(ks0), t_on], axis=1)
        init[:, 1] = np.clip(init[:, 1], v0_range[:, 0], v0_range[:, 1])
        theta, cov, chi2 = fit_curves(
            x, cfg, c, g, init, onset.sigma, v0_range, self.iterations, fit_spreading=cfg.contact.spreading
        )
        return CurveFit(theta, cov, chi2, onset.detected)

    def predict(self, X: np.ndarray) -> np.ndarray:
        x = heated_window(X, self.scene).astype(np.float64)
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


# -------------------------------------------------------------------------------------------------
# calibration of the user's sensor


def calibrate_sensor(
    touches: Sequence[Touch], config: ThermalConfig, fit_s: float = 2.0
) -> tuple[ThermalConfig, dict[str, Any]]:
    """Fit the sensor's own parameters from touches of known materials.

    Shared unknowns: heat capacity ``C``, loss ``G``, contact radius ``a``; per touch: baseline,
    ``V0``, ``log H``, the onset and ``log e`` (a Gaussian prior: the material's nominal value and
    property spread), over the first ``fit_s`` seconds of contact (a touch's
    ``release_s`` info column, when given, shortens that). ``scipy.optimize.least_squares`` (trust
    region, bounds) on the noise-weighted residuals. Also estimated: the sampling rate (median of
    the records), the noise (baseline), the ADC step (smallest level spacing of the readings, 0 if
    the readings look continuous). Returns the calibrated config and a summary.
    """
    from scipy.optimize import least_squares

    from tactile_learn.thermal_recordings import resample

    if not touches:
        raise DataError("calibration needs at least one labelled touch")
    fs = float(np.median([t.sampling_hz for t in touches]))
    step = _adc_step(touches)
    series = []
    for touch in touches:
        values, onset_samples = resample(touch, fs)
        det = detect_onset(values[None, :], fs, step)
        if onset_samples is None:
            if not det.detected[0]:
                raise DataError(f"{touch.file}: no contact found in the record (is the sensor heated?)")
            onset_samples = float(det.index[0]) + 0.5
        end = onset_samples + fit_s * fs
        if touch.info.get("release_s"):
            end = min(end, (float(touch.info["release_s"]) - touch.time_s[0]) * fs)
        n = int(min(len(values), math.floor(end) + 1))
        if n - onset_samples < 3:
            raise DataError(f"{touch.file}: too few samples of contact to calibrate from")
        mat = get_material(str(touch.material))
        pre = values[: max(int(onset_samples) - 2, 0)]
        # noise from the whole baseline when there is one (successive differences: drift-free)
        noise = math.sqrt(float(np.mean(np.diff(pre) ** 2)) / 2.0) if len(pre) >= 10 else float(det.sigma[0])
        series.append((values[:n], onset_samples / fs, mat, max(noise, 1e-3), float(det.baseline[0])))
    c0, g0 = nominal_sensor(config)
    r0 = math.sqrt(config.contact.radius_mm[0] * config.contact.radius_mm[1]) * 1e-3
    h_mid = math.sqrt(config.contact.conductance_w_m2k[0] * config.contact.conductance_w_m2k[1])
    spreading = config.contact.spreading
    # parameter vector: log C, log G, log a, then per touch (b, V0, log H, t0, log e)
    gauss = _material_gaussians([s[2] for s in series])
    p0 = [math.log(c0), math.log(g0), math.log(r0)]
    lo = [math.log(10.0), math.log(1e-3), math.log(1e-4)]
    hi = [math.log(1e6), math.log(1e5), math.log(1.0)]
    for (values, onset_s, _, _, base), (me, se, _, _) in zip(series, gauss, strict=True):
        p0 += [base, max(base - float(values[-1]), 0.1), math.log(h_mid), onset_s, me]
        lo += [-np.inf, -np.inf, math.log(10.0), onset_s - 2.0 / fs, me - 4 * se]
        hi += [np.inf, np.inf, math.log(1e8), onset_s + 2.0 / fs, me + 4 * se]
    sigma = np.array([max(s[3], 1e-3) for s in series])
    prior_h = max(0.5 * math.log(config.contact.conductance_w_m2k[1] / config.contact.conductance_w_m2k[0]), 1.0)

    def residuals(p: np.ndarray) -> np.ndarray:
        c, g, a = math.exp(p[0]), math.exp(p[1]), math.exp(p[2])
        out = []
        for i, (values, _, mat, _, _) in enumerate(series):
            b, v0, lh, t0, le = p[3 + 5 * i : 8 + 5 * i]
            t = np.arange(len(values)) / fs - t0
            e = math.exp(le)
            # the object's conductivity follows its effusivity at the material's diffusivity
            k = e * math.sqrt(mat.diffusivity_mm2_s * 1e-6)
            ks = float(spreading_conductance(k, a)) if spreading else 0.0
            f = _drop(
                t[None, :], np.array([c]), np.array([g]), np.array([e]), np.array([math.exp(lh)]), np.array([ks])
            )[0]
            out.append((values - (b - v0 * f)) / sigma[i])
            out.append(np.array([(lh - math.log(h_mid)) / (2 * prior_h)]))  # weak: H alone is poorly set
            out.append(np.array([(le - gauss[i, 0]) / gauss[i, 1]]))
        return np.concatenate(out)

    fit = least_squares(residuals, np.array(p0), bounds=(np.array(lo), np.array(hi)), x_scale="jac", max_nfev=400)
    p = fit.x
    c_fit, g_fit, a_fit = (math.exp(v) for v in p[:3])
    per = p[3:].reshape(-1, 5)
    h_fit = np.exp(per[:, 2])
    v0_fit = per[:, 1]
    baseline = per[:, 0]
    noise = float(np.median(sigma))
    # the calibrated scene: the fitted sensor with a small spread, the user's readout
    excess = float(np.median(v0_fit))  # objects near ambient on average: Q / G ~ V0
    sc, cc, rc = config.sensor, config.contact, config.readout
    heater = g_fit * max(excess, 0.5)
    ambient = baseline - excess
    sensor = dataclasses.replace(
        sc,
        heat_capacity_j_m2k=(round(c_fit * 0.97, 3), round(c_fit * 1.03, 3)),
        loss_w_m2k=(round(g_fit * 0.92, 4), round(g_fit * 1.08, 4)),
        heater_w_m2=(round(heater * 0.92, 3), round(heater * 1.08, 3)),
        ambient_c=(round(float(ambient.min()) - 2.0, 2), round(float(ambient.max()) + 2.0, 2)),
    )
    h_lo = float(np.clip(h_fit.min() / 2.0, 10.0, 1e8))
    h_hi = float(np.clip(max(h_fit.max() * 2.0, h_lo * 1.5), 10.0, 1e9))
    a_mm = a_fit * 1e3
    contact = dataclasses.replace(
        cc,
        conductance_w_m2k=(round(h_lo, 2), round(h_hi, 2)),
        radius_mm=(round(max(a_mm / 2.0, 0.1), 3), round(min(a_mm * 2.0, 1000.0), 3)),
    )
    readout = dataclasses.replace(rc, sampling_hz=round(fs, 6), noise_k=round(noise, 5), adc_step_k=round(step, 6))
    duration = max(readout.duration_s, config.window_s)
    readout = dataclasses.replace(readout, duration_s=duration)
    fitted = dataclasses.replace(config, sensor=sensor, contact=contact, readout=readout)
    summary = {
        "heat_capacity_j_m2k": c_fit,
        "loss_w_m2k": g_fit,
        "contact_radius_mm": a_mm,
        "conductance_w_m2k": [float(h_fit.min()), float(np.median(h_fit)), float(h_fit.max())],
        "v0_k": [float(v0_fit.min()), float(np.median(v0_fit)), float(v0_fit.max())],
        "sampling_hz": fs,
        "noise_k": noise,
        "adc_step_k": step,
        "rms_residual_sigma": float(np.sqrt(np.mean(fit.fun**2))),
        "solver_evaluations": int(fit.nfev),
    }
    return fitted, summary


def _adc_step(touches: Sequence[Touch]) -> float:
    """The readings' level spacing: the smallest positive difference between sorted distinct values,
    if most differences are near multiples of it; else 0 (continuous readings)."""
    values = np.unique(np.concatenate([t.temperature_c for t in touches]))
    gaps = np.diff(values)
    gaps = gaps[gaps > 1e-9]
    if len(gaps) < 10:
        return 0.0
    step = float(np.percentile(gaps, 5))
    ratio = gaps / step  # step > 1e-9
    on_grid = np.abs(ratio - np.round(ratio)) < 0.1
    return round(step, 6) if on_grid.mean() > 0.9 else 0.0
