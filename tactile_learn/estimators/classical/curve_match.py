"""The seed's thermal classifier: match a touch's response curve against a library of curves.

Input: one pixel's temperature window (B, W) in degC, ending "now" (the onset is somewhere
inside); output: class probabilities (B, K + 1) over the scene's materials and ``none`` (the pixel
touches nothing). The seed (its Fig. 7) matches the response "against a library of response
curves"; its copy gives no distance, so this one is the project's own, documented here.

1. **Onset alignment** (:func:`detect_onset`): baseline ``b`` (median) from the window's first
   0.1 s and noise ``sigma`` from the successive differences over its first 0.2 s (a flat run of
   padding at the start is skipped, unless the readings leave it for good where it ends: then it is
   a noise-free baseline); the departure ``dev = dir (b - x)`` (``dir`` = sign of the final departure, so a
   warm object works too) must exceed ``max(5 sigma, 2 ADC steps)`` on two consecutive samples; the
   onset sample ``k0`` is the last sample before that crossing still within ``1.5 sigma`` of the
   baseline. The baseline is then re-estimated from the samples before ``k0``.
2. **Library** (:class:`CurveLibrary`): for every material at its nominal properties, the scene's
   nominal sensor (mid-range heat capacity and loss), a grid of contact conductances (5, log-spaced
   over the scene's range) and contact radii (2), the normalised drop ``f(t) = 1 - v(t)/V0``
   sampled at ``t_j = (j - 1 + phi)/fs`` for ``j = -J..L``: the true onset lies ``phi`` samples
   before sample ``k0 + 1``, ``phi`` in {0.25, 0.5, 0.75, 1, 1.5, 2, 3, 4} (``f = 0`` before onset),
   which absorbs a detection late by up to 3 samples.
3. **Distance**: the observed drop ``y_j = dir (b - x[k0 + j])``, ``j = -J..end``, against each
   template ``tau`` with a free amplitude ``a >= 0`` (the unknown object temperature sets ``V0``):
   ``RSS(tau) = |y|^2 - max(y.tau, 0)^2 / |tau|^2``. A material's score is
   ``-min over its templates of RSS / (2 sigma^2)`` (the Gaussian log-likelihood with the amplitude
   profiled out); ``none`` scores ``-|y|^2 / (2 sigma^2) + 3`` (a material must explain at least
   ``6 sigma^2`` of the signal's energy). Probabilities are the softmax of the scores; a pixel
   without a detected onset is ``none``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from synth.materials import Material
from synth.scene import Scene
from synth.sensors.thermal import ContactModel, ThermalConfig, spreading_conductance
from tactile_learn.estimators.base import Estimator

__all__ = [
    "CurveLibrary",
    "CurveMatchEstimator",
    "Onset",
    "detect_onset",
    "drop_segments",
    "heated_window",
    "merge_classes",
    "nominal_sensor",
    "softmax",
]

#: samples before the detected onset that the alignment may reach back to
LOOKBACK = 3
#: onset phases (in samples before sample k0 + 1) of the library's templates
PHASES: tuple[float, ...] = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0)
#: mean of the squares of ~10 standard normals without the largest (noise estimate's correction)
_TRIM_FACTOR = 0.69
#: log-score bonus of ``none`` (nats): a material must explain 2 * NONE_BONUS sigma^2 of energy
NONE_BONUS = 3.0


@dataclass(frozen=True)
class Onset:
    """Per-curve onset detection (arrays of length B)."""

    index: np.ndarray  # k0: last baseline sample (int); W - 1 when nothing was detected
    detected: np.ndarray  # bool
    baseline: np.ndarray  # degC
    sigma: np.ndarray  # K, noise s.d. estimate (floored)
    direction: np.ndarray  # +1 the pixel cools on contact (object colder), -1 it warms


def nominal_sensor(config: ThermalConfig) -> tuple[float, float]:
    """Mid-range heat capacity and loss of the scene's sensor."""
    s = config.sensor
    return float(np.mean(s.heat_capacity_j_m2k)), float(np.mean(s.loss_w_m2k))


def detect_onset(x: np.ndarray, fs: float, adc_step: float = 0.0, base_s: float = 0.1) -> Onset:
    """Onset alignment of curves ``x`` (B, W) (see the module docstring, step 1).

    A flat run (3 or more equal samples) at the window's start is taken for padding and skipped
    when estimating the baseline and the noise, unless the readings leave its value for good right
    where it ends (they depart strictly monotonically, cross the threshold within ``LOOKBACK``
    samples and never come back): then it is a noise-free baseline (a clean or sub-LSB-noise
    sensor), skipping it would estimate the noise from the contact itself, and the curve is detected
    without the skip (baseline: the run's value; noise: the floor).
    """
    x = np.asarray(x, dtype=np.float64)
    w = x.shape[1]
    # a window that starts before its record is padded with the record's first sample: skip that
    # flat run (3 or more equal samples) when estimating the noise
    flat = np.cumprod(x == x[:, :1], axis=1).sum(axis=1)
    start = np.where(flat >= 3, flat - 1, 0)
    n0 = int(min(max(3, round(base_s * fs)), max(1, w // 2)))
    onset, _ = _detect_from(x, start, np.full(len(x), w), n0, adc_step)
    runs = np.flatnonzero(start > 0)
    if len(runs):
        # the other reading: the run is the baseline (its value) and the noise (none: the floor)
        xr = x[runs]
        plain, k1 = _detect_from(xr, np.zeros(len(runs), dtype=np.int64), flat[runs], n0, adc_step)
        end = flat[runs] - 1  # the run's last sample
        idx = np.arange(w)[None, :]
        dev = plain.direction[:, None] * (xr[:, :1] - xr)
        back = (idx >= k1[:, None]) & (dev <= 1.5 * plain.sigma[:, None])
        # the first samples after the run depart strictly monotonically (noise around a padded value
        # does not: it settles at once)
        rise = np.diff(dev, axis=1, prepend=0.0)
        stall = (idx > end[:, None]) & (idx <= end[:, None] + 1 + LOOKBACK) & (rise <= 0)
        baseline_run = plain.detected & (k1 <= end + LOOKBACK) & ~back.any(axis=1) & ~stall.any(axis=1)
        rows = runs[baseline_run]
        for name in ("index", "detected", "baseline", "sigma", "direction"):
            getattr(onset, name)[rows] = getattr(plain, name)[baseline_run]
    return onset


def _detect_from(
    x: np.ndarray, start: np.ndarray, stop: np.ndarray, n0: int, adc_step: float
) -> tuple[Onset, np.ndarray]:
    """:func:`detect_onset` with the baseline and noise spans starting at sample ``start`` (B,) and
    ending before ``stop`` (B,); also returns the first threshold crossing ``k1`` (B,) (``W - 1``
    when nothing was detected)."""
    w = x.shape[1]
    idx = np.arange(w)[None, :]
    inside = idx < stop[:, None]
    first = (idx >= start[:, None]) & (idx < start[:, None] + n0) & inside
    with warnings.catch_warnings():  # a window that is flat throughout: all-NaN rows
        warnings.simplefilter("ignore", RuntimeWarning)
        b0 = np.nanmedian(np.where(first, x, np.nan), axis=1)
    b0 = np.where(np.isfinite(b0), b0, x[:, -1])
    floor = max(adc_step / math.sqrt(12.0), 1e-3)  # quantisation noise; never a zero sigma
    span = (idx >= start[:, None]) & (idx < start[:, None] + 2 * n0) & inside
    # noise from successive differences (robust to a slow drift, exact for quantised readings,
    # unlike a median): the mean square without the largest one (a stray onset), d ~ N(0, 2 s^2)
    pair = span[:, 1:] & span[:, :-1]
    d2 = np.where(pair, np.diff(x, axis=1) ** 2, 0.0)
    count = pair.sum(axis=1)
    trimmed = (d2.sum(axis=1) - d2.max(axis=1, initial=0.0)) / np.maximum(count - 1, 1)  # count - 1 >= 1 where used
    sigma0 = np.where(count >= 3, np.sqrt(trimmed / (2.0 * _TRIM_FACTOR)), 0.0)
    sigma0 = np.maximum(sigma0, floor)
    tail = x[:, -min(3, w) :].mean(axis=1)
    direction = np.where(tail <= b0, 1.0, -1.0)
    dev = direction[:, None] * (b0[:, None] - x)
    thr = np.maximum(5.0 * sigma0, 2.0 * adc_step)[:, None]
    above = dev > thr
    both = above.copy()
    both[:, :-1] &= above[:, 1:]
    detected = both.any(axis=1)
    k1 = np.where(detected, np.argmax(both, axis=1), w - 1)
    quiet = (dev <= 1.5 * sigma0[:, None]) & (idx < k1[:, None])
    k0 = np.where(quiet.any(axis=1), np.where(quiet, idx, -1).max(axis=1), np.maximum(k1 - 1, 0))
    k0 = np.where(detected, k0, w - 1)
    # baseline again from the samples before the onset (at least 3, else the first n0)
    upto = np.maximum(k0 - 1, 0)
    use = idx < upto[:, None]
    count = use.sum(axis=1)
    mean = np.where(use, x, 0.0).sum(axis=1) / np.maximum(count, 1)  # count >= 1 where used
    baseline = np.where(count >= 3, mean, b0)
    return Onset(k0.astype(np.int64), detected, baseline, sigma0, direction), k1


def drop_segments(x: np.ndarray, onset: Onset, lookback: int = LOOKBACK) -> tuple[np.ndarray, np.ndarray]:
    """Observed drops ``y`` (B, J + W) aligned at the onset (``y[:, J + j]`` is sample ``k0 + j``,
    zero past the window's end) and the number of valid entries per curve."""
    x = np.asarray(x, dtype=np.float64)
    w = x.shape[1]
    j = np.arange(-lookback, w)[None, :]
    src = onset.index[:, None] + j
    valid = (src >= 0) & (src < w)
    vals = np.take_along_axis(x, np.clip(src, 0, w - 1), axis=1)
    y = np.where(valid, onset.direction[:, None] * (onset.baseline[:, None] - vals), 0.0)
    n_valid = lookback + w - onset.index  # entries from j = -J up to the window's last sample
    return y, n_valid


def softmax(scores: np.ndarray) -> np.ndarray:
    z = scores - scores.max(axis=1, keepdims=True)
    e = np.exp(z)
    return e / e.sum(axis=1, keepdims=True)  # the maximum term is exp(0) = 1: never 0/0


class CurveLibrary:
    """Normalised template drops for every material, conductance, radius and onset phase."""

    def __init__(
        self,
        config: ThermalConfig,
        materials: tuple[Material, ...],
        length: int,
        n_conductance: int = 5,
        n_radius: int = 2,
        phases: tuple[float, ...] = PHASES,
        lookback: int = LOOKBACK,
    ) -> None:
        fs = config.readout.sampling_hz
        c, g = nominal_sensor(config)
        cc = config.contact
        hs = np.geomspace(cc.conductance_w_m2k[0], cc.conductance_w_m2k[1], n_conductance)
        radii = np.linspace(cc.radius_mm[0], cc.radius_mm[1], n_radius) * 1e-3
        mat, hh, rr, ph = np.meshgrid(np.arange(len(materials)), hs, radii, np.asarray(phases), indexing="ij")
        mat, hh, rr, ph = mat.ravel(), hh.ravel(), rr.ravel(), ph.ravel()
        e = np.array([m.effusivity for m in materials])[mat]
        k = np.array([m.k_w_mk for m in materials])[mat]
        ks = spreading_conductance(k, rr) if cc.spreading else np.zeros_like(k)
        model = ContactModel.create(c, g, hh, e, ks, 1.0, 0.0)
        j = np.arange(-lookback, length)
        t = (j[None, :] - 1 + ph[:, None]) / fs
        drop = 1.0 - model.excess(np.maximum(t, 0.0))
        self.templates = np.where(t >= 0, drop, 0.0)  # (M, J + length)
        self.material = mat
        self.conductance = hh
        self.radius_m = rr
        self.phase = ph
        self.n_materials = len(materials)
        self.lookback = lookback
        self.cum_sq = np.cumsum(self.templates**2, axis=1)

    def match(self, y: np.ndarray, n_valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per curve: the smallest RSS of every material (B, K) and the best template index (B,)."""
        dots = y @ self.templates.T  # (B, M); y is zero past each curve's end
        col = np.clip(n_valid - 1, 0, self.cum_sq.shape[1] - 1)
        norms = self.cum_sq[:, col].T  # (B, M): |tau|^2 over each curve's valid span
        yy = (y * y).sum(axis=1, keepdims=True)
        gain = np.where(norms > 0, np.maximum(dots, 0.0) ** 2 / np.where(norms > 0, norms, 1.0), 0.0)
        rss = np.maximum(yy - gain, 0.0)
        per_mat = np.full((len(y), self.n_materials), np.inf)
        for m in range(self.n_materials):
            per_mat[:, m] = rss[:, self.material == m].min(axis=1)
        return per_mat, rss.argmin(axis=1)


class CurveMatchEstimator(Estimator):
    """Library curve matching with onset alignment (the seed's method)."""

    task = "thermal"
    name = "curve_match"

    def __init__(self, scene: Scene, n_conductance: int = 5, n_radius: int = 2) -> None:
        self.scene = scene
        self.n_conductance = n_conductance
        self.n_radius = n_radius

    @cached_property
    def library_(self) -> CurveLibrary:
        cfg: ThermalConfig = self.scene.sensor
        return CurveLibrary(cfg, cfg.material_list, cfg.window_samples, self.n_conductance, self.n_radius)

    def scores(self, x: np.ndarray) -> tuple[np.ndarray, Onset, np.ndarray]:
        """Log-scores (B, K + 1), the onsets, and the best template of every curve."""
        cfg: ThermalConfig = self.scene.sensor
        onset = detect_onset(x, cfg.readout.sampling_hz, cfg.readout.adc_step_k)
        y, n_valid = drop_segments(x, onset, self.library_.lookback)
        rss, best = self.library_.match(y, n_valid)
        var = 2.0 * onset.sigma[:, None] ** 2
        yy = (y * y).sum(axis=1)
        none = -yy / var[:, 0] + NONE_BONUS
        scores = np.concatenate([-rss / var, none[:, None]], axis=1)
        scores[~onset.detected, :-1] = -np.inf
        scores[~onset.detected, -1] = 0.0
        return scores, onset, best

    def predict(self, X: np.ndarray) -> np.ndarray:
        x = heated_window(X, self.scene)
        if len(x) == 0:
            return np.zeros((0, len(self.scene.sensor.class_names) + 1), dtype=np.float32)
        scores, _, _ = self.scores(x)
        return merge_classes(softmax(scores), self.scene.sensor).astype(np.float32)


def heated_window(X: np.ndarray, scene: Scene) -> np.ndarray:
    """The checked input's heated channel (B, W): the seed's methods read that one only."""
    from tactile_learn.tasks.thermal import ThermalTask

    x = ThermalTask().check_inputs(X, scene)
    return x[:, 0] if x.ndim == 3 else x


def merge_classes(prob: np.ndarray, config: ThermalConfig) -> np.ndarray:
    """Probabilities over materials (+ none) summed into the scene's classes (+ none)."""
    if not config.objects.classes:
        return prob
    k = len(config.class_names)
    out = np.zeros((len(prob), k + 1), dtype=prob.dtype)
    for m, c in enumerate(config.class_of_material):
        out[:, c] += prob[:, m]
    out[:, k] = prob[:, -1]
    return out
