"""The seed's thermal classifier: match a touch's response curve against a library of curves.

Input: one pixel's temperature window (B, W) in degC, ending "now" (the onset is somewhere
inside); output: class probabilities (B, K + 1) over the scene's materials and ``none`` (the pixel
touches nothing; ``predict_proba`` gives them, ``predict`` the most probable). The seed (its
Fig. 7) matches the response "against a library of response curves"; its copy gives no distance,
so this one is the project's own, documented here.

1. **Onset alignment** (:func:`~tactile_learn.thermal_signal.detect_onset`): baseline ``b`` (median)
   from the window's first 0.1 s and noise ``sigma`` from the successive differences over its first
   0.2 s (a flat run of padding at the start is skipped, unless the readings leave it for good where
   it ends: then it is a noise-free baseline); the departure ``dev = dir (b - x)`` (``dir`` = sign
   of the final departure, so a warm object works too) must exceed ``max(5 sigma, 2 ADC steps)`` on
   two consecutive samples; the onset sample ``k0`` is the last sample before that crossing still
   within ``1.5 sigma`` of the baseline. The baseline is then re-estimated from the samples before
   ``k0``.
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

A single curve (batch 1, the streaming case) is aligned by :mod:`tactile_learn.thermal_frame`
(the same steps on one vector, equal to the batch functions' results) and matched against the
library's transposed copy (``(J + W, M)``, built in ``prepare``) through the rows its drop fills:
``y`` is zero past the window's end, so the dot products read only its ``n_valid`` first samples
of each template (half the library's memory for a mid-window onset; at batch 1 the product is
bound by reading the library, not by arithmetic). Scores stay float64: they are RSS over
``2 sigma^2`` of a signal many thousand ``sigma^2`` strong, where float32 would move them by
whole nats.
"""

from __future__ import annotations

import numpy as np

from synth.materials import Material
from synth.scene import Scene
from synth.sensors.thermal import ContactModel, ThermalConfig, spreading_conductance
from tactile_learn.estimators.base import Classifier
from tactile_learn.thermal_frame import detect_onset_one, drop_segment_one
from tactile_learn.thermal_signal import LOOKBACK, Onset, detect_onset, drop_segments
from tactile_learn.validation.thermal import thermal_check, thermal_input

__all__ = [
    "CurveLibrary",
    "CurveMatchEstimator",
    "Onset",
    "detect_onset",
    "drop_segments",
    "heated",
    "heated_window",
    "merge_classes",
    "nominal_sensor",
    "softmax",
]

#: onset phases (in samples before sample k0 + 1) of the library's templates
PHASES: tuple[float, ...] = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0)
#: log-score bonus of ``none`` (nats): a material must explain 2 * NONE_BONUS sigma^2 of energy
NONE_BONUS = 3.0


def nominal_sensor(config: ThermalConfig) -> tuple[float, float]:
    """Mid-range heat capacity and loss of the scene's sensor."""
    s = config.sensor
    return float(np.mean(s.heat_capacity_j_m2k)), float(np.mean(s.loss_w_m2k))


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
        # one curve's layout: a sample's values over every template contiguous, so the samples a
        # drop fills are one block of rows
        self.templates_t = np.ascontiguousarray(self.templates.T)  # (J + length, M)
        self.cum_sq_t = np.ascontiguousarray(self.cum_sq.T)

    def match(self, y: np.ndarray, n_valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per curve: the smallest RSS of every material (B, K) and the best template index (B,)."""
        dots = y @ self.templates.T  # (B, M); y is zero past each curve's end
        col = np.clip(n_valid - 1, 0, self.cum_sq.shape[1] - 1)
        norms = self.cum_sq[:, col].T  # (B, M): |tau|^2 over each curve's valid span
        yy = (y * y).sum(axis=1, keepdims=True)
        gain = np.where(norms > 0, np.maximum(dots, 0.0) ** 2 / np.where(norms > 0, norms, 1.0), 0.0)
        rss = np.maximum(yy - gain, 0.0)
        # templates are ordered material first (the library's meshgrid): one block per material
        per_mat = rss.reshape(len(y), self.n_materials, -1).min(axis=2)
        return per_mat, rss.argmin(axis=1)

    def match_one(self, y: np.ndarray, n_valid: int) -> np.ndarray:
        """:meth:`match`'s smallest RSS of every material (K,) for one drop ``y`` (J + W,) whose
        first ``n_valid`` entries are filled."""
        n = min(max(n_valid, 1), len(self.cum_sq_t))
        dots = y[:n] @ self.templates_t[:n]  # y is zero from n on
        norms = self.cum_sq_t[n - 1]
        positive = norms > 0
        np.maximum(dots, 0.0, out=dots)
        gain = np.divide(dots * dots, norms, out=np.zeros_like(dots), where=positive)
        rss = np.maximum(float(y @ y) - gain, 0.0)
        return rss.reshape(self.n_materials, -1).min(axis=1)


class CurveMatchEstimator(Classifier):
    """Library curve matching with onset alignment (the seed's method)."""

    task = "thermal"
    name = "curve_match"

    def __init__(self, scene: Scene, n_conductance: int = 5, n_radius: int = 2) -> None:
        self.scene = scene
        self.n_conductance = n_conductance
        self.n_radius = n_radius

    def prepare(self) -> CurveMatchEstimator:
        """Build the template library of the scene's materials (once)."""
        if "library_" not in self.__dict__:
            cfg: ThermalConfig = self.scene.sensor
            self.input_check_ = thermal_check(cfg)
            self.library_ = CurveLibrary(cfg, cfg.material_list, cfg.window_samples, self.n_conductance, self.n_radius)
        return self

    def scores(self, x: np.ndarray, onset: Onset | None = None) -> tuple[np.ndarray, Onset, np.ndarray]:
        """Log-scores (B, K + 1), the onsets, and the best template of every curve ``x`` (B, W)
        (heated channel); ``onset``: the curves' onsets when the caller has detected them already."""
        library: CurveLibrary = self.prepared_state("library_")
        cfg: ThermalConfig = self.scene.sensor
        if onset is None:
            onset = detect_onset(x, cfg.readout.sampling_hz, cfg.readout.adc_step_k)
        y, n_valid = drop_segments(x, onset, library.lookback)
        rss, best = library.match(y, n_valid)
        var = 2.0 * onset.sigma[:, None] ** 2
        yy = (y * y).sum(axis=1)
        none = -yy / var[:, 0] + NONE_BONUS
        scores = np.concatenate([-rss / var, none[:, None]], axis=1)
        scores[~onset.detected, :-1] = -np.inf
        scores[~onset.detected, -1] = 0.0
        return scores, onset, best

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        return self.predict_proba_checked(self.prepared_state("input_check_")(X))

    def predict_proba_checked(self, x: np.ndarray) -> np.ndarray:
        x = heated(x)
        library: CurveLibrary = self.prepared_state("library_")  # an unprepared estimator fails before any work
        if len(x) == 0:
            return np.zeros((0, len(self.scene.sensor.class_names) + 1), dtype=np.float32)
        if len(x) == 1:
            scores = self._scores_one(x[0], library)[None]
        else:
            scores, _, _ = self.scores(x)
        return merge_classes(softmax(scores), self.scene.sensor).astype(np.float32)

    def _scores_one(self, x: np.ndarray, library: CurveLibrary) -> np.ndarray:
        """:meth:`scores`' log-scores (K + 1,) of one curve ``x`` (W,)."""
        cfg: ThermalConfig = self.scene.sensor
        onset = detect_onset_one(x, cfg.readout.sampling_hz, cfg.readout.adc_step_k)
        scores = np.full(library.n_materials + 1, -np.inf)
        if not onset.detected:
            scores[-1] = 0.0
            return scores
        y, n_valid = drop_segment_one(x, onset, library.lookback)
        var = 2.0 * onset.sigma**2
        np.divide(library.match_one(y, n_valid), -var, out=scores[:-1])
        scores[-1] = -float(y @ y) / var + NONE_BONUS
        return scores


def heated(x: np.ndarray) -> np.ndarray:
    """The heated channel (B, W) of a validated batch (B, W) or (B, C, W): the seed's methods read
    that one only."""
    return x[:, 0] if x.ndim == 3 else x


def heated_window(X: np.ndarray, scene: Scene) -> np.ndarray:
    """The validated input's heated channel (B, W)."""
    return heated(thermal_input(X, scene.sensor))


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
