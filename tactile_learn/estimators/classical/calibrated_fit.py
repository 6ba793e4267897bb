"""Calibrated fit: the scene's full sensor model against every channel, object temperature unknown.

The seed's methods read the heated curve alone with the seed's sensor (no lag, no heater control,
a step contact). This one uses everything a calibrated scene knows (:mod:`synth.sensors.thermal_touch`):
per class (its nominal effusivity), a small grid of the nuisances the scene leaves open (contact
conductance, contact build-up, where the contact starts in the window), the basis curves of every
input channel; then, per curve and template, linear least squares of

    heated  = R0 + r drift + (R0 + r lead - T_obj) obj [- Q power]      passive = P0 + r_p drift_p + (...) obj_p

over the window, with the object's temperature ``T_obj`` shared by the channels (the physics that
lets a passive channel tell a cooled wood from a metal at room temperature), ``R0``, ``P0``, the
drifts and, for a heater switched off on contact, the ambient it loses heat to, all free. A class's
score is ``-min RSS / (2 sigma^2)`` over its templates (``sigma``: the scene's noise, at least
10 mK: the calibration's model error), softmax over the classes and ``none`` (every channel a
straight line, with curve matching's bonus). The contact's start is searched on a 0.2 s grid over
the window (no onset detection: a drifting baseline fools threshold detectors, and the thermistors'
lag puts the visible departure well after the touch).

Every design's orthonormal basis is prepared once (dense) and then factored per contact start
(:mod:`.calibrated_one_curve`): a batch is one product of the curves with every start's basis of
its templates' span and one batched product per start (~2.5 times fewer multiply-adds than the
dense bases); a single curve (``predict`` of one row, and the streaming path:
:meth:`CalibratedFitEstimator.one_frame_run`, :meth:`~CalibratedFitEstimator.frame_runner`) reads
the same factors through :class:`~.calibrated_one_curve_run.OneCurveRun`: its check and scores in
the fewest numpy calls, giving the batch's probabilities within 1e-7.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from synth.errors import ConfigError
from synth.scene import Scene
from synth.sensors.thermal import ThermalConfig, spreading_conductance
from synth.sensors.thermal.dynamics import ChannelModel, channel_terms
from tactile_learn.estimators.base import Classifier, labels_of
from tactile_learn.estimators.classical.calibrated_one_curve import StartFactoredBases
from tactile_learn.estimators.classical.calibrated_one_curve_run import OneCurveRun
from tactile_learn.estimators.classical.curve_match import NONE_BONUS, softmax
from tactile_learn.validation.thermal import thermal_check, thermal_input_shape

__all__ = ["CalibratedFitEstimator"]

#: smallest noise s.d. the scores assume (K): what a calibrated model leaves unexplained
MODEL_ERROR_K = 0.01
#: grid step (s) of the contact start searched over the window
STEP_S = 0.2


def _mid(bounds: tuple[float, float], log: bool = False) -> float:
    lo, hi = bounds
    return math.sqrt(lo * hi) if log and lo > 0 else 0.5 * (lo + hi)


class CalibratedFitEstimator(Classifier):
    """The scene's sensor model fitted per class to every input channel (see the module docstring)."""

    task = "thermal"
    name = "calibrated"

    def __init__(self, scene: Scene, n_conductance: int = 3, n_ramp: int = 2, chunk: int = 256) -> None:
        self.scene = scene
        self.n_conductance = n_conductance
        self.n_ramp = n_ramp
        self.chunk = chunk

    def prepare(self) -> CalibratedFitEstimator:
        """Build every template's basis columns and their least-squares projections (once)."""
        if "templates_" not in self.__dict__:
            self.input_check_ = thermal_check(self.scene.sensor)
            self.templates_ = self._templates()
            self.projections_ = self._projections()
            self.one_curve_ = self._one_curve()
            cfg: ThermalConfig = self.scene.sensor
            self.one_run_ = OneCurveRun.build(self.one_curve_, thermal_input_shape(cfg), self.input_check_.bounds())
        return self

    def _templates(self) -> tuple[np.ndarray, np.ndarray]:
        """Basis columns (M, S, 3W + 1, 4) of every template, indexed by the sample relative to the
        contact start (offset W), and each template's class (M,)."""
        cfg: ThermalConfig = self.scene.sensor
        sc, cc, pc = cfg.sensor, cfg.contact, cfg.passive
        fs = cfg.readout.sampling_hz
        w = cfg.window_samples
        t = (np.arange(3 * w + 1) - w) / fs  # contacts up to a third of a window before its start
        mats, of = cfg.material_list, cfg.class_of_material
        hs = np.geomspace(*cc.conductance_w_m2k, self.n_conductance) if cc.conductance_w_m2k[0] > 0 else [1.0]
        ramps = np.linspace(*cc.ramp_s, self.n_ramp)
        radius = _mid(cc.radius_mm) * 1e-3
        columns, owner = [], []
        heater_off = sc.heater in ("off", "step")
        for k in range(len(cfg.class_names)):
            members = [m for m, c in zip(mats, of, strict=True) if c == k]
            e = math.exp(float(np.mean([math.log(m.effusivity) for m in members])))
            kk = math.exp(float(np.mean([math.log(m.k_w_mk) for m in members])))
            ks = float(spreading_conductance(kk, radius)) if cc.spreading else 0.0
            for h in hs:
                for ramp in ramps:
                    per_channel = []
                    for channel in cfg.channels:
                        if channel == "heated":
                            cap, loss = _mid(sc.heat_capacity_j_m2k), _mid(sc.loss_w_m2k)
                            lags = (_mid(sc.lag_s), _mid(sc.lag2_s))
                            gains = (_mid(sc.controller_kp), _mid(sc.controller_ki))
                            hh = h
                        else:
                            cap, loss = _mid(pc.heat_capacity_j_m2k), _mid(pc.loss_w_m2k)
                            lags = (_mid(pc.lag_s), _mid(pc.lag2_s))
                            gains = (0.0, 0.0)
                            hh = _mid(pc.conductance_w_m2k, log=True) * h / _mid(cc.conductance_w_m2k, log=True)
                        model = ChannelModel.create(
                            heat_capacity=cap,
                            loss=loss,
                            conductance=hh,
                            effusivity=e,
                            spreading=ks,
                            lag1_s=lags[0],
                            lag2_s=lags[1],
                            kp=gains[0],
                            ki=gains[1],
                        )
                        off = np.array([_mid(sc.heater_off_s)]) if (heater_off and channel == "heated") else None
                        terms = channel_terms(model, t[None, :], np.array([ramp]), off)
                        lead = lags[0] + lags[1]
                        drift = terms.drift[0] if sc.heater != "held" or channel != "heated" else 0.0 * t
                        cols = [1.0 + terms.obj[0], drift + lead * terms.obj[0], -terms.obj[0], 0.0 * t]
                        if terms.power is not None and sc.heater == "off":  # Q = G (R0 + r lead - T_amb) + C r
                            cols[0] = cols[0] - loss * terms.power[0]
                            cols[1] = cols[1] - (loss * lead + cap) * terms.power[0]
                            cols[3] = loss * terms.power[0]
                        elif terms.power is not None:  # step: the power change is a free amplitude
                            cols[3] = terms.power[0]
                        per_channel.append(np.stack(cols, axis=-1))
                    columns.append(np.stack(per_channel))
                    owner.append(k)
        return np.stack(columns), np.array(owner)

    def _projections(self) -> tuple[np.ndarray, np.ndarray, int, bool]:
        """Orthonormal bases of every (contact start, template) design matrix and of the
        no-contact lines, side by side ``(S W, (G + 1) L)``: the ``G`` = starts x templates groups
        of ``L`` columns sorted by class (zero-padded where a design has lower rank), the lines
        last; where each class's groups begin (K,); ``L``; and whether the bases leave out the
        constant (see :func:`_column_bases`: a curve is then centred first).

        The design matrices do not depend on the curves, so they are factorised once here: a
        curve's residual sum of squares against a design ``A`` is ``|y|^2 - |Q^T y|^2`` (``Q`` an
        orthonormal basis of ``A``'s columns), and every template, start and the lines of a batch
        are one matrix product ``y @ Q``. (Solving each least-squares problem per call
        factorised every design matrix again on every call: at batch 1 nearly all of the time.)
        """
        cfg: ThermalConfig = self.scene.sensor
        basis, owner = self.prepared_state("templates_")
        n_ch = basis.shape[1]
        w = cfg.window_samples
        fs = cfg.readout.sampling_hz
        heater_off = cfg.sensor.heater in ("off", "step")
        n_lin = 2 * n_ch + 1 + (1 if heater_off else 0)
        starts, design_start, design_template = self._design_keys()
        designs = []
        for s, m in zip(design_start, design_template, strict=True):
            rel = np.arange(w) - starts[s] + w  # index into the templates' time axis
            cols = basis[m][:, rel]  # (S, W, 4): the same for every curve
            a = np.zeros((n_ch * w, n_lin))
            for c in range(n_ch):
                rows = slice(c * w, (c + 1) * w)
                a[rows, 2 * c] = cols[c, :, 0]
                a[rows, 2 * c + 1] = cols[c, :, 1]
                a[rows, 2 * n_ch] = cols[c, :, 2]
                if heater_off:
                    a[rows, -1] = cols[c, :, 3]
            designs.append(a)
        group_class = owner[design_template]
        t = np.arange(w) / fs
        line = np.zeros((n_ch * w, 2 * n_ch))
        for c in range(n_ch):
            line[c * w : (c + 1) * w, 2 * c] = 1.0
            line[c * w : (c + 1) * w, 2 * c + 1] = t
        lines = np.zeros((n_ch * w, n_lin))  # padded to the designs' width
        lines[:, : 2 * n_ch] = line
        if not np.array_equal(np.unique(group_class), np.arange(len(cfg.class_names))):
            raise ConfigError(f"calibrated fit: every class needs a template ({cfg.class_names})")
        q, n_columns, centred = _column_bases(np.concatenate([np.stack(designs), lines[None]]))
        return q, np.flatnonzero(np.r_[True, group_class[1:] != group_class[:-1]]), n_columns, centred

    def _design_keys(self) -> tuple[list[int], np.ndarray, np.ndarray]:
        """The contact starts searched (samples into the window: up to a third of a window before
        it, on the ``STEP_S`` grid), and the (start index, template index) of every design in the
        bases' order: by class (stable), then start, then template."""
        cfg: ThermalConfig = self.scene.sensor
        _, owner = self.prepared_state("templates_")
        w = cfg.window_samples
        step = max(1, round(STEP_S * cfg.readout.sampling_hz))
        starts = list(range(-w // 3, w - step, step))
        design_start = np.repeat(np.arange(len(starts)), len(owner))
        design_template = np.tile(np.arange(len(owner)), len(starts))
        by_class = np.argsort(owner[design_template], kind="stable")
        return starts, design_start[by_class], design_template[by_class]

    def _one_curve(self) -> StartFactoredBases:
        """The bases factored per contact start for single curves (:mod:`.calibrated_one_curve`)."""
        q, _, n_columns, centred = self.prepared_state("projections_")
        _, owner = self.prepared_state("templates_")
        _, design_start, design_template = self._design_keys()
        sigma = max(self.scene.sensor.readout.noise_k, MODEL_ERROR_K)
        return StartFactoredBases.build(q, n_columns, centred, design_start, design_template, owner, sigma, NONE_BONUS)

    def predict(self, X: np.ndarray) -> np.ndarray:
        run = self.__dict__.get("one_run_")
        if run is not None:  # one plain valid curve: checked and scored at once (calibrated_one_curve_run)
            out = run(X)
            if out is not None:
                return out.argmax(axis=1)  # int64: labels_of without its conversions
        return labels_of(self.predict_proba_checked(self.prepared_state("input_check_")(X)))

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        run = self.__dict__.get("one_run_")
        if run is not None:  # as predict's
            out = run(X)
            if out is not None:
                return out
        return self.predict_proba_checked(self.prepared_state("input_check_")(X))

    def predict_proba_checked(self, X: np.ndarray) -> np.ndarray:
        run: OneCurveRun = self.prepared_state("one_run_")  # an unprepared estimator fails before any work
        if len(X) == 1:  # one curve: the bases factored per start, its own layout
            return run.probabilities(X)
        cfg: ThermalConfig = self.scene.sensor
        x = np.asarray(X, dtype=np.float64)
        if x.ndim == 2:
            x = x[:, None, :]
        k = len(cfg.class_names)
        out = np.zeros((len(x), k + 1), dtype=np.float32)
        for start in range(0, len(x), self.chunk):
            out[start : start + self.chunk] = self._predict(x[start : start + self.chunk])
        return out

    def _predict(self, x: np.ndarray) -> np.ndarray:
        b, n_ch, w = x.shape
        # every (start, template) and the lines at once, through the bases factored per contact
        # start (measured 7.2 against 17.7 us a curve for the dense bases' product at chunk 256)
        return softmax(self.prepared_state("one_curve_").scores(x.reshape(b, n_ch * w).copy()))

    def frame_runner(self) -> Callable[[np.ndarray], np.ndarray]:
        """A function of one validated curve ``(1, *shape)`` giving what :meth:`predict_proba_checked`
        gives (:class:`~tactile_learn.frame_stream.FrameStream` calls it for the single frames of an
        ungated stream that passed its own check)."""
        run: OneCurveRun = self.prepared_state("one_run_")
        return run.probabilities

    def one_frame_run(self) -> Callable[[object], np.ndarray | None]:
        """A function of one frame giving its probabilities where it is a plain valid curve (float32,
        the scene's shape, inside the ADC's range: checked from its mean and spread, most curves with
        no pass of their own), else ``None``
        (:class:`~tactile_learn.frame_stream.FrameStream` calls it first for the frames of an
        ungated stream; ``None`` sends a frame through the stream's own checks and their errors)."""
        run: OneCurveRun = self.prepared_state("one_run_")
        return run


def _column_bases(designs: np.ndarray) -> tuple[np.ndarray, int, bool]:
    """Orthonormal bases of the column spaces of ``designs`` (G, N, L), side by side (N, G L'),
    ``L'``, and whether the constant vector was left out of them.

    The rank is decided as ``numpy.linalg.lstsq`` (``rcond=None``) decides it: singular values
    above ``eps max(N, L)`` times the largest; the columns beyond the rank are zero (a design whose
    contact lies outside the window has fewer independent columns). (Leaving them out, with a
    sum over uneven groups, measured slower than multiplying by the zeros.)

    Where the constant vector lies in every design's column space (the calibrated designs: the
    baseline's column plus the object's, the lines' offset), the bases are those of the designs
    with their constant part removed, ``L' = L - 1``: a centred curve's residual against a design
    is then ``|y|^2 - |Q^T y|^2`` with a third less to read (batch 1 reads the whole matrix once
    per call) and with ``|y|^2`` the curve's variation, not its level (less cancellation)."""
    g, n, n_col = designs.shape
    u, sv, _ = np.linalg.svd(designs, full_matrices=False)
    floor = np.finfo(np.float64).eps * max(n, n_col) * sv[:, :1]
    basis = u * (sv > floor)[:, None, :]
    ones = np.full(n, 1.0 / math.sqrt(n))
    outside = ones - np.einsum("gnl,gl->gn", basis, np.einsum("gnl,n->gl", basis, ones))
    centred = n_col > 1 and bool((np.linalg.norm(outside, axis=1) <= 1e-8).all())  # rounding: ~1e-15
    if centred:
        without = designs - ones[None, :, None] * np.einsum("n,gnl->gl", ones, designs)[:, None, :]
        u, sv, _ = np.linalg.svd(without, full_matrices=False)  # rank one less than the design's
        n_col -= 1
        basis = u[:, :, :n_col] * (sv[:, :n_col] > floor)[:, None, :]
    return np.ascontiguousarray(basis.transpose(1, 0, 2).reshape(n, g * n_col)), n_col, centred
