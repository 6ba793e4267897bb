"""Calibration of a real thermal fingertip (heated and optional passive thermistor) from labelled touches.

The model (:mod:`synth.sensors.thermal_dynamics`, every term a verified closed form): each channel
is a lumped body (heat capacity ``C``, loss ``G``) read through two thermistor lags, touching the
object through a contact conductance ``H``; the object (a semi-infinite body of its class's
effusivity ``e`` and a contact patch of radius ``a``: spreading conductance ``4 k / (pi a)``) has
an unknown temperature, the same for both channels. The contact builds up over a ramp starting a
lead before the onset (the force's half-plateau crossing, or the curve's departure), each channel
may drift before contact (a heater still settling, the approach to a cold object), and the heater's
power changes at a delay after the onset: by ``-(G (R0 + r (tau_1 + tau_2) - T_amb) + C r)`` with a
fitted ``T_amb`` (a rig that switches its heater off on contact: ``T_amb`` is the ambient; a
controller that goes on heating: ``T_amb`` above the set point, a rise)::

    reading_c(t) = R0_c + r_c drift_c(t) + (R0_c + r_c (tau_1 + tau_2) - T_obj) obj_c(t)
                   - [heated] (G (R0 + r (tau_1 + tau_2) - T_amb) + C r) power(t - t_off)

The temperatures identify only ``e / C``, ``G / C`` and ``H / C``: each class's effusivity is fixed
at its library value (geometric mean over its materials), which sets the scale. Fitted (nonlinear,
multi-start ``scipy.optimize.least_squares``, trust region with bounds, short runs from jittered
starts, the best run to convergence): the heated channel's ``C, G, H``, the passive one's ``G`` and
its ``C`` and ``H`` as ratios to the heated twin's (within a factor 10 and 20: objects at the passive
thermistor's own temperature give it no signal, so its scale is barely seen), each channel's sum of
lags and its split (kept away from equal lags, a double root), the radius ``a``, the contact's lead
and ramp and the time of the heater's power change. Linear, solved exactly inside every evaluation (variable
projection): per touch ``R0_c, r_c, T_obj``, and the shared ``T_amb``, with weak priors that keep
them physical when a channel alone cannot pin them (``T_obj`` within ~25 K of the sensor, drifts of
a few tenths of K/s). Then every touch is refitted alone for its own contact (a conductance factor,
lead and ramp): their spread is the touch-to-touch variation a calibrated scene draws from. Last
(``touch_contact``), the shared parameters and every touch's own contact are refined together (a
press is never the same twice: a real user's touches have their own contact; weak priors tie them
to the shared one, with which they trade off), with a Jacobian that steps all touches' own
parameters at once (each moves its own touch's rows only). Optional per-touch nuisance terms
(``nuisance``, linear, closed forms in :func:`synth.sensors.thermal.dynamics.nuisance_terms`): the
object's flux (its temperature not uniform with depth), the heater's power steps, and a contact
precursor (part of the contact arriving over the ``PRECURSOR_S`` before it, one amplitude per
channel). Optional and nonlinear: the approach through the closing air gap (two shared parameters)
and contact events (``"contact_events"``: each channel's contact conductance steps by a bounded
factor at events placed at the kinks of the own-contact residual, :mod:`.thermal_events`; per-touch
parameters of the joint refinement). Optional too (``noise_weighted``): the joint refinement in
units of each sample's noise s.d. (the maximum-likelihood fit in the unit the residual is reported
in) with weak linear priors.

Noise (what a residual is measured against): the recorder adds white noise ``sigma_w`` (from the
pre-contact segment) and jitters its time stamps by ``sigma_t`` (estimated from how far each curve
strays from a smooth spline relative to its slope), so ``sigma(t)^2 = sigma_w^2 + (sigma_t dx/dt)^2``.
A second unit, ``precontact_k``, is the scatter of the segment before any contact about a quadratic
trend (the noise's whole per-sample variance, its correlated parts included); the report gives
both (``rms_sigma``, ``rms_sigma_precontact``), with each touch's own contact (the headline) and with
one shared contact (``shared_contact``).
The report gives the fit's residual in those units, every parameter with its bounds, the ones at a
bound (with the likely reason), and the ones the data do not identify (posterior s.d. above a factor
of 2, or a correlation above 0.99 with another).
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import optimize
from scipy.interpolate import LSQUnivariateSpline

from synth.errors import DataError
from synth.materials import Material
from synth.sensors.thermal.approach import approach_term
from synth.sensors.thermal.contact_events import contact_event_terms
from synth.sensors.thermal.dynamics import ChannelModel, channel_terms, nuisance_terms
from synth.sensors.thermal.readout import drift_ending_at_contact
from tactile_learn.calibration.thermal_events import place_events
from tactile_learn.calibration.thermal_kinks import residual_kinks, residual_windows

__all__ = ["CalibrationResult", "FitTouch", "Parameter", "calibrate_channels", "noise_levels", "prepare_touches"]


#: rate (Hz) the curves are fitted at: the curves are smooth (lags of tenths of a second)
FIT_HZ = 20.0
#: the fit starts this long before the onset (earlier samples hold the heater's settling)
PRE_S = 0.3
#: the contact starts at most this long before the onset
LEAD_MAX_S = 1.5
#: the noise's pre-contact segment ends this long before the onset (a press's first touch comes
#: ~0.3 s before its force's half-plateau crossing on the robot recordings)
QUIET_BEFORE_S = 0.5
#: prior s.d. of the object's temperature around the sensor's (K) and of a drift (K/s)
OBJECT_PRIOR_K = 25.0
DRIFT_PRIOR_K_S = 0.5
#: a linear value one prior s.d. away costs as much as one sample this far off (K). The shared fit
#: keeps 1 K (the priors steer its multi-start away from unphysical drifts); the noise-weighted joint
#: refinement uses 10 mK, weak next to a record's ~150 samples (1 K against 10 mK residuals pulls
#: the pre-contact drifts, and through them the shared ambient: at R_1's fit 9.9/9.8 mK with them,
#: 8.2/9.2 mK without)
PRIOR_ROW_K = 1.0
PRIOR_ROW_TOUCH_K = 0.01
#: a parameter whose log s.d. exceeds this (a factor 2) is reported as not identified
UNIDENTIFIED_LOG_SD = math.log(2.0)
#: what the model is expected to leave unexplained (K): the data residuals' unit in the fit
MODEL_ERROR_K = 0.01
#: weak priors: s.d. of a scale parameter's log (a factor 10) and of a time (s)
PRIOR_LOG_SD = math.log(10.0)
PRIOR_LINEAR_SD = 1.0
#: the priors' weight (0: off). Off by default: on the robot recordings they moved the fit to worse
#: local minima without making two sessions agree (the report lists what the data leave free)
PRIOR_WEIGHT = 0.0
#: per-touch nuisance terms the fit may add (see synth.sensors.thermal.dynamics.nuisance_terms)
NUISANCE_TERMS = ("object_flux", "heater_steps", "contact_precursor", "approach", "contact_events", "drift_ends")
#: the pre-contact drift as a READING-side change that the contact ends (``"drift_ends"`` in
#: ``nuisance``; synth.sensors.thermal.readout.drift_ending_at_contact): on these channels the drift's
#: slope relaxes to 0 from the contact's start through its own lag (a shared parameter per channel,
#: ``<channel>.drift_end_s``), with no net heating after the contact, in place of the default drift
#: (a heater still settling, which goes on heating through the contact and the lags)
DRIFT_ENDS_CHANNELS: tuple[str, ...] = ("heated",)
#: the drift's end lag's bounds (s)
DRIFT_END_S = (0.01, 5.0)
#: the approach (``"approach"`` in ``nuisance``; synth.sensors.thermal.approach): heat through the
#: closing air gap before the contact, no per-touch amplitude but two SHARED parameters (the
#: effective residual gap g0 and the approach speed); the gap's flux is integrated over this
#: window before the contact, on a grid of APPROACH_HZ (0.04 % of the term against the
#: finite-volume solution at 50 Hz, 0.5-0.8 % at 25 Hz)
APPROACH_WINDOW_S = 2.0
APPROACH_HZ = 25.0
#: contact events (``"contact_events"`` in ``nuisance``; synth.sensors.thermal.contact_events): the
#: contact conductance steps at events placed at the kinks of every touch's own-contact residual
#: (tactile_learn.calibration.thermal_events: both channels jointly, one event time for both),
#: refined jointly with the touches' own contacts. Per event: a factor on each channel's contact
#: conductance, within [1 / EVENT_FACTOR_MAX, EVENT_FACTOR_MAX] (a slip or creep of the pad changes
#: its real contact area, not by more than about twofold while the force holds), and a shift of its
#: time within +-EVENT_SHIFT_S (the placement's grid is 0.05 s); the Volterra quadrature on a grid of
#: EVENT_HZ (0.01-0.02 % of the term against the finite-volume solution)
EVENT_FACTOR_MAX = 2.0
#: one factor per event for both channels (the pad's real contact area changes alike under both
#: thermistors) instead of one per channel
EVENT_FACTOR_SHARED = False
EVENT_SHIFT_S = (-0.15, 0.15)
EVENT_HZ = 25.0
#: the contact precursor's length (s before the contact start): see NUISANCE_TERMS
PRECURSOR_S = 0.6
#: the terms with shared parameters only (no per-touch amplitude)
_SHARED_TERMS = ("approach", "drift_ends")
_NUISANCE_DOC = {
    "object_flux": "the object's flux F = k g (its temperature not uniform with depth: a cooled block warming "
    "from its surface)",
    "heater_steps": "the heater's power steps at the contact and at t_off (a controller's response read as steps)",
    "contact_precursor": "a fraction of the contact arriving early (building up over the PRECURSOR_S before the "
    "contact: an uneven pad, a thinning air gap), one amplitude per channel",
    "approach": "(shared) heat through the closing air gap before the contact, h = 1 / (1 / H + (g0 + v (-t)) / "
    "k_air), k_air = 0.026 W/(m K): no amplitude of its own",
    "contact_events": "contact events: each channel's contact conductance steps by a bounded factor at the kinks "
    "of its residual (slip or creep of the pad; one event time for both channels)",
    "drift_ends": "(shared) the pre-contact drift a reading-side change that the contact ends through its own lag "
    "(no net heating after the contact)",
}
#: the joint refinement (shared + every touch's own contact) fits every sample in units of its
#: noise s.d. (white noise and timing jitter, see noise_levels), with weak priors (PRIOR_ROW_TOUCH_K):
#: the maximum-likelihood fit under the noise model the residual is reported in. Off, every sample
#: of both channels weighs the same in K (the passive channel's white noise is ~7 times smaller).
#: Off by default: on R_1 it lowers the residual in sigma (37 -> 30) by trading the heated channel's
#: mK for the passive one's (see the README's calibration section)
NOISE_WEIGHTED = False
#: solver evaluations of the joint refinement (shared + every touch's own contact)
TOUCH_RUN = 40
#: solver evaluations of each multi-start's short run
SHORT_RUN = 15


@dataclass(frozen=True)
class Parameter:
    name: str
    unit: str
    lo: float
    hi: float
    start: float
    log: bool = True
    doc: str = ""

    def to_free(self, value: float) -> float:
        return math.log(value) if self.log else value

    def from_free(self, value: float) -> float:
        return math.exp(value) if self.log else value


_CHANNEL_PARAMS = (
    ("heat_capacity_j_m2k", "J/(m^2 K)", 20.0, 2e5, 2000.0, "heat capacity per area C"),
    ("loss_w_m2k", "W/(m^2 K)", 0.01, 2e4, 30.0, "loss G to the surroundings"),
    ("conductance_w_m2k", "W/(m^2 K)", 2.0, 2e5, 700.0, "contact conductance H"),
    ("lags_s", "s", 0.01, 10.0, 0.8, "sum of the thermistor lags tau_1 + tau_2"),
    (
        "lag_share",
        "",
        0.52,
        0.995,
        0.7,
        "tau_1 / (tau_1 + tau_2): kept away from 1/2, where equal lags are a double root",
    ),
)


#: the passive channel's heat capacity and contact conductance as ratios to the heated twin's:
#: (lowest, highest, start)
_TWIN_RATIOS = {"heat_capacity_j_m2k": (0.1, 10.0, 0.5), "conductance_w_m2k": (0.05, 10.0, 0.5)}


#: every touch's own contact (relative to the shared one): log conductance factor, lead offset (s),
#: log build-up factor; ``hi`` is also the s.d. of its weak prior (in TOUCH_PRIOR_SD units)
_TOUCH_CONTACT = (
    Parameter("touch.log_conductance_factor", "", -math.log(10.0), math.log(10.0), 0.0, False, "log H factor"),
    Parameter("touch.lead_offset_s", "s", -0.5, 0.5, 0.0, False, "contact start relative to the shared lead"),
    Parameter("touch.log_ramp_factor", "", -math.log(30.0), math.log(30.0), 0.0, False, "log build-up factor"),
)
#: the touches' own contacts' prior s.d., as a fraction of their bounds
TOUCH_PRIOR_SD = 0.5


@dataclass
class FitTouch:
    """One labelled touch on the fitting grid: times ``t`` (s, record time), channels (degC),
    the onset (s, record time) and the class index."""

    file: str
    label: int
    t: np.ndarray
    heated: np.ndarray
    passive: np.ndarray | None
    onset_s: float


@dataclass
class CalibrationResult:
    """The fitted values (by parameter name), per-touch values, the noise, and the report."""

    values: dict[str, float]
    per_touch: list[dict[str, float]]
    noise: dict[str, float]
    report: dict[str, Any] = field(default_factory=dict)


def prepare_touches(
    series: Sequence[tuple[str, int, np.ndarray, np.ndarray, np.ndarray | None, float]], fs: float = FIT_HZ
) -> list[FitTouch]:
    """Resample ``(file, label, time_s, heated, passive, onset_s)`` records to ``fs`` from
    ``PRE_S`` before the onset (or the record's start) to the record's end."""
    out = []
    for file, label, time_s, heated, passive, onset in series:
        start = max(float(time_s[0]), onset - PRE_S)
        grid = start + np.arange(math.floor((float(time_s[-1]) - start) * fs + 1e-9) + 1) / fs
        if grid[-1] - onset < 1.0:
            raise DataError(f"{file}: less than 1 s of contact after the onset ({onset:.3f} s): too short to calibrate")
        out.append(
            FitTouch(
                file,
                label,
                grid,
                np.interp(grid, time_s, heated),
                None if passive is None else np.interp(grid, time_s, passive),
                onset,
            )
        )
    return out


def noise_levels(series: Sequence[tuple[np.ndarray, np.ndarray, float]]) -> dict[str, float]:
    """White noise and timing jitter of records ``(time_s, values, onset_s)`` (one channel).

    Each record is smoothed by a least-squares cubic spline with knots every 0.25 s (which follows
    every physical change of these sensors); ``sigma_w`` is the RMS of what it leaves before the
    onset, ``sigma_t`` the median over records of that remainder's RMS divided by the slope's RMS
    where the curve moves faster than 0.1 K/s (time-stamp jitter moves a sample by ``slope * dt``),
    ``precontact_k`` the median scatter of the segment before any contact about a quadratic trend
    (the noise's whole variance per sample, correlated parts included; see :func:`_residual_summary`).
    """
    white, jitter, pre_scatter = [], [], []
    for t, x, onset in series:
        # before any contact: the scatter about a quadratic trend (the heater's settling), every
        # correlated component up to the segment's length
        quiet = (t > t[0] + 0.05) & (t < onset - QUIET_BEFORE_S)
        if quiet.sum() >= 20:
            tq = t[quiet] - t[quiet].mean()
            trend = np.polyval(np.polyfit(tq, x[quiet], 2), tq)
            pre_scatter.append(float(np.sqrt(np.mean((x[quiet] - trend) ** 2))))
        knots = np.arange(t[0] + 0.25, t[-1] - 0.2, 0.25)
        if len(knots) < 4:
            continue
        spline = LSQUnivariateSpline(t, x, knots, k=3)
        rest = x - spline(t)
        slope = spline.derivative()(t)
        pre = (t < onset - 0.1) & (t > t[0] + 0.1)
        if pre.sum() >= 20:
            white.append(float(np.sqrt(np.mean(rest[pre] ** 2))))
        moving = np.abs(slope) > 0.1
        if moving.sum() >= 50:
            jitter.append(float(np.sqrt(np.mean(rest[moving] ** 2) / np.mean(slope[moving] ** 2))))
    return {
        "white_k": float(np.median(white)) if white else 1e-3,
        "timing_jitter_s": float(np.median(jitter)) if jitter else 0.0,
        "precontact_k": float(np.median(pre_scatter)) if pre_scatter else (float(np.median(white)) if white else 1e-3),
    }


def _class_nominal(materials: Sequence[Material]) -> tuple[float, float]:
    """A class's effusivity and diffusivity (m^2/s): geometric means over its library materials."""
    e = math.exp(float(np.mean([math.log(m.effusivity) for m in materials])))
    alpha = math.exp(float(np.mean([math.log(m.diffusivity_mm2_s * 1e-6) for m in materials])))
    return e, alpha


class _Problem:
    """The variable-projection least-squares problem over a batch of touches."""

    def __init__(
        self,
        touches: list[FitTouch],
        classes: Sequence[Sequence[Material]],
        heater_off: bool,
        nuisance: Sequence[str] = (),
        noise: dict[str, dict[str, float]] | None = None,
    ) -> None:
        self.touches = touches
        unknown = set(nuisance) - set(NUISANCE_TERMS)
        if unknown:
            raise ValueError(f"unknown nuisance term(s) {sorted(unknown)}: choose from {NUISANCE_TERMS}")
        #: per-touch nuisance terms (linear): the object's flux (a temperature not uniform with
        #: depth) and the heater's power steps at the contact and at t_off (in place of the shared ambient)
        self.nuisance = tuple(n for n in NUISANCE_TERMS if n in nuisance and (n != "heater_steps" or heater_off))
        #: the linear columns they add (before T_obj)
        self.nuisance_columns = [
            *(["object_flux_w_m2"] if "object_flux" in self.nuisance else []),
            *(["heater_step_at_contact_w_m2", "heater_step_at_off_w_m2"] if "heater_steps" in self.nuisance else []),
            *(["heated_precursor_k"] if "contact_precursor" in self.nuisance else []),
        ]
        self.n = len(touches)
        self.passive = all(t.passive is not None for t in touches)
        #: the channels whose pre-contact drift the contact ends (see DRIFT_ENDS_CHANNELS)
        self.drift_end_channels = tuple(
            ch
            for ch in (("heated", "passive") if self.passive else ("heated",))
            if "drift_ends" in self.nuisance and ch in DRIFT_ENDS_CHANNELS
        )
        if "contact_precursor" in self.nuisance and self.passive:
            self.nuisance_columns.append("passive_precursor_k")
        #: the joint refinement fits in noise units (see NOISE_WEIGHTED)
        self.noise_weighted = noise is not None
        self.heater_off = heater_off
        self.length = max(len(t.t) for t in touches)
        n, w = self.n, self.length
        self.mask = np.zeros((n, w), dtype=bool)
        self.t = np.zeros((n, w))
        self.x = np.zeros((2, n, w))
        for i, tc in enumerate(touches):
            m = len(tc.t)
            self.mask[i, :m] = True
            self.t[i, :m] = tc.t
            self.t[i, m:] = tc.t[-1]
            self.x[0, i, :m] = tc.heated
            if tc.passive is not None:
                self.x[1, i, :m] = tc.passive
        self.onset = np.array([tc.onset_s for tc in touches])
        #: every sample's weight (C, n, W): 1 / its noise s.d. (normalised to mean square 1), or 1
        self.weight = self._noise_weights(noise)
        self.label = np.array([tc.label for tc in touches])
        params: list[Parameter] = []
        channels = ("heated", "passive") if self.passive else ("heated",)
        for ch in channels:
            for name, unit, lo, hi, start, doc in _CHANNEL_PARAMS:
                log = name != "lag_share"
                if ch == "passive" and name in _TWIN_RATIOS:
                    # a passive thermistor's scale is hardly seen (objects at its own temperature give
                    # it no signal): its C and H are held within a factor of the heated twin's
                    r_lo, r_hi, r_start = _TWIN_RATIOS[name]
                    ratio = name.replace("_j_m2k", "").replace("_w_m2k", "") + "_ratio"
                    doc = f"{doc}, relative to the heated channel's"
                    params.append(Parameter(f"passive.{ratio}", "", r_lo, r_hi, r_start, True, doc))
                    continue
                first = start if ch == "heated" or not log else start / 4
                params.append(Parameter(f"{ch}.{name}", unit, lo, hi, first, log, doc))
        # the temperatures identify only e / C, G / C, H / C: each class's effusivity is fixed at its
        # library value (the geometric mean over its materials), which sets the scale of C
        self.class_e = np.array([_class_nominal(mats)[0] for mats in classes])
        self.class_alpha = np.array([_class_nominal(mats)[1] for mats in classes])
        params.append(Parameter("contact.radius_mm", "mm", 0.1, 50.0, 5.0, True, "contact patch radius a"))
        params.append(Parameter("contact.lead_s", "s", -0.3, LEAD_MAX_S, 0.1, False, "contact start before the onset"))
        params.append(Parameter("contact.ramp_s", "s", 0.02, 2.0, 0.1, True, "contact build-up time"))
        if heater_off:
            params.append(
                Parameter("heater.off_after_onset_s", "s", -1.5, 1.5, 0.0, False, "time of the heater's power change")
            )
        if "approach" in self.nuisance:
            # physical ranges: a residual gap from a polished to a rough, tilted pad; a robot's slow
            # final approach (mm/s)
            params.append(
                Parameter("approach.gap_um", "um", 1.0, 3000.0, 200.0, True, "residual air gap g0 at contact")
            )
            params.append(Parameter("approach.speed_mm_s", "mm/s", 0.1, 50.0, 2.0, True, "approach speed v"))
        for ch in self.drift_end_channels:
            doc = "lag with which the contact ends the reading's pre-contact drift"
            params.append(Parameter(f"{ch}.drift_end_s", "s", *DRIFT_END_S, 0.3, True, doc))
        self.shared = params
        self.per_touch: list[Parameter] = []
        #: per-touch contact quality: every channel's H times this (1 in the shared fit)
        self.h_scale = np.ones(self.n)
        #: the linear priors' row scale (see PRIOR_ROW_K)
        self.prior_row_k = PRIOR_ROW_K
        #: contact events' times (n, K) after each onset (NaN: none), set by with_events
        self.event_t: np.ndarray | None = None

    def _noise_weights(self, noise: dict[str, dict[str, float]] | None) -> np.ndarray:
        """1 / sigma(t) of every sample, ``sigma^2 = sigma_w^2 + (sigma_t dx/dt)^2`` with the data's
        own slope (the noise model of :func:`noise_levels`, the unit the report's residual is given
        in: a fit in that unit is the maximum-likelihood one), normalised to a mean square of 1 over
        the samples (the residual rows keep their scale against the priors); 1 without ``noise``."""
        n_ch = 2 if self.passive else 1
        weight = np.ones((n_ch, self.n, self.length))
        if noise is None:
            return weight
        for c, ch in enumerate(("heated", "passive")[:n_ch]):
            nz = noise[ch]
            slope = np.gradient(self.x[c], axis=1) * FIT_HZ
            weight[c] = 1.0 / np.sqrt(nz["white_k"] ** 2 + (nz["timing_jitter_s"] * slope) ** 2)
        weight *= self.mask[None]
        return weight / np.sqrt(np.mean(weight[:, self.mask] ** 2))

    def with_events(self, times: Sequence[Sequence[float]]) -> _Problem:
        """The same problem with contact events at ``times`` (per touch, s after its onset): their
        factors and time shifts become per-touch parameters of :meth:`with_touch_contact`."""
        twin = copy.copy(self)
        slots = max((len(row) for row in times), default=0)
        twin.event_t = np.full((self.n, slots), np.nan)
        for i, row in enumerate(times):
            twin.event_t[i, : len(row)] = row
        return twin

    def _event_parameters(self) -> list[Parameter]:
        """Per event slot: each channel's log conductance factor and the time shift (see EVENT_*)."""
        if self.event_t is None:
            return []
        bound = math.log(EVENT_FACTOR_MAX)
        out = []
        for k in range(self.event_t.shape[1]):
            for ch in self._event_channels():
                doc = f"log of the {ch} contact conductance factor at the touch's event {k}"
                out.append(Parameter(f"event{k}.{ch}_log_factor", "", -bound, bound, 0.0, False, doc))
            doc = f"shift of event {k}'s time from the kink's"
            out.append(Parameter(f"event{k}.shift_s", "s", *EVENT_SHIFT_S, 0.0, False, doc))
        return out

    def _event_channels(self) -> tuple[str, ...]:
        """Whose factor an event has: each channel's, or one for both (EVENT_FACTOR_SHARED)."""
        if EVENT_FACTOR_SHARED and self.passive:
            return ("both",)
        return ("heated", "passive") if self.passive else ("heated",)

    def events(self, free: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The events' times (n, K) after each onset and every channel's factors (C, n, K), or None."""
        if self.event_t is None or not self.per_touch or self.event_t.shape[1] == 0:
            return None
        names = [p.name for p in self.per_touch]
        k0, n = len(self.shared), self.n

        def values(name: str) -> np.ndarray:
            g = names.index(name)
            return free[k0 + g * n : k0 + (g + 1) * n]

        slots = range(self.event_t.shape[1])
        times = self.event_t + np.stack([values(f"event{k}.shift_s") for k in slots], axis=1)
        channels = self._event_channels()
        factors = np.exp(
            np.stack([np.stack([values(f"event{k}.{ch}_log_factor") for k in slots], axis=1) for ch in channels])
        )
        if channels == ("both",):
            factors = np.concatenate([factors, factors])
        return times, factors

    def with_touch_contact(self, noise: dict[str, dict[str, float]] | None = None) -> _Problem:
        """The same problem with every touch's own contact (free, after the shared fit): its
        conductance factor, its lead and its build-up time relative to the shared ones, each with a
        weak prior (they trade off with the shared contact)."""
        twin = copy.copy(self)
        twin.per_touch = list(_TOUCH_CONTACT) + self._event_parameters()
        if noise is not None:  # data rows in noise units: the priors' rows weak beside them
            twin.prior_row_k = PRIOR_ROW_TOUCH_K
            twin.weight = twin._noise_weights(noise)
            twin.noise_weighted = True
        return twin

    def fit_from(self, x0: np.ndarray, nfev: int) -> optimize.OptimizeResult:
        """A bounded least-squares run of at most ``nfev`` evaluations from ``x0`` (clipped inside
        the bounds), forward differences: one run of the multi-start."""
        lo, hi = self.bounds()
        return optimize.least_squares(
            self.residuals,
            np.clip(x0, lo + 1e-9, hi - 1e-9),
            bounds=(lo, hi),
            x_scale="jac",
            max_nfev=nfev,
            diff_step=1e-5,
        )

    @property
    def n_free(self) -> int:
        return len(self.shared)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = [p.to_free(p.lo) for p in self.shared] + [p.to_free(p.lo) for p in self.per_touch for _ in range(self.n)]
        hi = [p.to_free(p.hi) for p in self.shared] + [p.to_free(p.hi) for p in self.per_touch for _ in range(self.n)]
        return np.array(lo), np.array(hi)

    def start(self) -> np.ndarray:
        return np.array(
            [p.to_free(p.start) for p in self.shared]
            + [p.to_free(p.start) for p in self.per_touch for _ in range(self.n)]
        )

    def unpack(self, free: np.ndarray) -> tuple[dict[str, float], np.ndarray, np.ndarray]:
        values = {p.name: p.from_free(float(v)) for p, v in zip(self.shared, free[: len(self.shared)], strict=True)}
        for name in _TWIN_RATIOS:
            ratio = name.replace("_j_m2k", "").replace("_w_m2k", "") + "_ratio"
            if f"passive.{ratio}" in values:
                values[f"passive.{name}"] = values[f"heated.{name}"] * values[f"passive.{ratio}"]
        for ch in ("heated", "passive"):
            if f"{ch}.lags_s" in values:
                values[f"{ch}.lag_s"] = values[f"{ch}.lags_s"] * values[f"{ch}.lag_share"]
                values[f"{ch}.lag2_s"] = values[f"{ch}.lags_s"] * (1.0 - values[f"{ch}.lag_share"])
        lead = np.full(self.n, values["contact.lead_s"])
        ramp = np.full(self.n, values["contact.ramp_s"])
        if self.per_touch:
            k, n = len(self.shared), self.n
            self.h_scale = np.exp(free[k : k + n])
            lead = lead + free[k + n : k + 2 * n]
            ramp = ramp * np.exp(free[k + 2 * n : k + 3 * n])
        return values, lead, ramp

    def channel_model(self, values: dict[str, Any], channel: str, effusivity: Any, spreading: Any) -> ChannelModel:
        """One channel's lumped model from the unpacked parameters (every touch's contact scale applied)."""
        return ChannelModel.create(
            heat_capacity=values[f"{channel}.heat_capacity_j_m2k"],
            loss=values[f"{channel}.loss_w_m2k"],
            conductance=values[f"{channel}.conductance_w_m2k"] * self.h_scale,
            effusivity=effusivity,
            spreading=spreading,
            lag1_s=values[f"{channel}.lag_s"],
            lag2_s=values[f"{channel}.lag2_s"],
        )

    def design(self, free: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Columns (C, n, W, 3) per channel (R0, drift, obj), the heater's power column (n, W) and the
        per-touch nuisance columns (C, n, W, K) (K = 0 without them)."""
        values, lead, ramp = self.unpack(free)
        radius = values["contact.radius_mm"] * 1e-3
        e = self.class_e[self.label]
        alpha = self.class_alpha[self.label]
        spreading = 4.0 * e * np.sqrt(alpha) / (math.pi * radius)  # 4 k / (pi a), k = e sqrt(alpha)
        t_rel = self.t - (self.onset - lead)[:, None]
        channels = ("heated", "passive") if self.passive else ("heated",)
        cols = np.zeros((len(channels), self.n, self.length, 3))
        power = np.zeros((self.n, self.length))
        extra = np.zeros((len(channels), self.n, self.length, self.n_nuisance))
        events = self.events(free)
        for c, ch in enumerate(channels):
            model = self.channel_model(values, ch, e, spreading)
            t_off = lead + values["heater.off_after_onset_s"] if (c == 0 and self.heater_off) else None
            terms = channel_terms(model, t_rel, ramp, t_off)
            obj, drift, step = terms.obj, terms.drift, terms.power
            if events is not None:  # the contact conductance's steps (times from the contact's start)
                # (clipped at the contact's start: an event before it would be part of the build-up)
                at = np.maximum(events[0] + lead[:, None], 0.0)
                ev = contact_event_terms(model, t_rel, ramp, at, events[1][c], t_off, EVENT_HZ)
                obj = obj + ev.obj
                # a drift's net heating C r flows out through the changed contact too
                drift = drift + values[f"{ch}.heat_capacity_j_m2k"] * ev.heating
                step = None if step is None or ev.power is None else step + ev.power
            if "approach" in self.nuisance:  # the gap's exchange, per kelvin of the same V0
                gap, speed = values["approach.gap_um"] * 1e-6, values["approach.speed_mm_s"] * 1e-3
                obj = obj + approach_term(model, t_rel, ramp, gap, speed, APPROACH_WINDOW_S, APPROACH_HZ)
            if self.n_nuisance:  # per-touch linear columns (the approach has none)
                # the object's flux (one amplitude per touch for both channels: the same object),
                # then the heater's steps (heated channel only) at the contact and at t_off
                steps = "heater_steps" in self.nuisance and c == 0
                times = (np.zeros(self.n), lead + values["heater.off_after_onset_s"]) if steps else ()
                early = PRECURSOR_S if "contact_precursor" in self.nuisance else 0.0
                more = nuisance_terms(model, t_rel, ramp, times, early)
                j = 0
                if "object_flux" in self.nuisance:
                    extra[c, :, :, 0] = more.flux
                    j = 1
                if steps:
                    extra[c, :, :, j], extra[c, :, :, j + 1] = more.steps[0], more.steps[1]
                if more.precursor is not None:  # each channel's own column (its own V0 and place on the pad)
                    extra[c, :, :, self.nuisance_columns.index(f"{ch}_precursor_k")] = more.precursor
            lead_lag = values[f"{ch}.lag_s"] + values[f"{ch}.lag2_s"]
            reading_drift = ch in self.drift_end_channels
            # reading = R0 + r drift + (R0 + r lead_lag - T_obj) obj: T_obj's column is -obj
            cols[c, :, :, 0] = 1.0 + obj
            cols[c, :, :, 1] = drift + lead_lag * obj
            if reading_drift:  # the reading drifts, not the body: V0 = R0 - T_obj, no heating after
                cols[c, :, :, 1] = drift_ending_at_contact(t_rel, values[f"{ch}.drift_end_s"])
            cols[c, :, :, 2] = -obj
            if step is not None:
                # the heater's power at the switch: its loss to the ambient plus the net heating,
                # Q = G (R0 + r lead_lag - T_amb) + C r; it drops to 0 at t_off
                g, cap = values[f"{ch}.loss_w_m2k"], values[f"{ch}.heat_capacity_j_m2k"]
                cols[c, :, :, 0] -= g * step
                if not reading_drift:  # a reading-side drift heats nothing
                    cols[c, :, :, 1] -= (g * lead_lag + cap) * step
                power = g * step  # the column of T_amb (shared by every touch)
        return cols, power, extra

    @property
    def n_nuisance(self) -> int:
        return len(self.nuisance_columns)

    def solve(self, free: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Residuals (C, n, W) (0 outside each record), linear values (n, 2C + 1), and ``Q``."""
        cols, power, extra = self.design(free)
        n_ch = cols.shape[0]
        k = self.n_nuisance
        m = 2 * n_ch + 1 + k  # R0 and drift per channel, the nuisance terms, then T_obj
        a = np.zeros((self.n, n_ch * self.length + 1 + n_ch, m))
        y = np.zeros((self.n, n_ch * self.length + 1 + n_ch))
        q = np.zeros((self.n, n_ch * self.length + 1 + n_ch))
        w = self.mask.astype(float)
        for c in range(n_ch):
            rows = slice(c * self.length, (c + 1) * self.length)
            wc = self.weight[c] * w
            a[:, rows, 2 * c] = cols[c, :, :, 0] * wc
            a[:, rows, 2 * c + 1] = cols[c, :, :, 1] * wc
            a[:, rows, -1] = cols[c, :, :, 2] * wc
            a[:, rows, 2 * n_ch : 2 * n_ch + k] = extra[c] * wc[:, :, None]
            y[:, rows] = self.x[c] * wc
        q[:, : self.length] = power * self.weight[0] * w
        # weak priors (rows after the data): T_obj near the first channel's onset value, drifts small
        base = np.array([tc.heated[max(int(np.searchsorted(tc.t, tc.onset_s)) - 1, 0)] for tc in self.touches])
        ref = base if not self.passive else np.array([tc.passive[0] for tc in self.touches if tc.passive is not None])
        prior = n_ch * self.length
        a[:, prior, -1] = self.prior_row_k / OBJECT_PRIOR_K
        y[:, prior] = ref * self.prior_row_k / OBJECT_PRIOR_K
        for c in range(n_ch):
            a[:, prior + 1 + c, 2 * c + 1] = self.prior_row_k / DRIFT_PRIOR_K_S
        # variable projection with the shared ambient T_amb: per touch x = A+ (y - T_amb q), then
        # T_amb by 1-D least squares of the projected residuals
        scale = np.sqrt((a**2).sum(axis=1)) + 1e-12
        an = a / scale[:, None, :]
        pinv = np.linalg.pinv(an)  # (n, m, rows)
        # (A (A+ y)): two matrix-vector products per touch, not one three-operand sum
        proj_y = y - (an @ (pinv @ y[:, :, None]))[:, :, 0]
        proj_q = q - (an @ (pinv @ q[:, :, None]))[:, :, 0]
        denom = float((proj_q**2).sum())
        # (with per-touch heater steps the shared ambient is one of their combinations: not fitted)
        shared_ambient = self.heater_off and "heater_steps" not in self.nuisance and denom > 0
        power_q = float((proj_q * proj_y).sum()) / denom if shared_ambient else 0.0
        sol = np.einsum("nmk,nk->nm", pinv, y - power_q * q) / scale
        fit = np.einsum("nrm,nm->nr", a, sol) + power_q * q
        res = (fit - y)[:, : n_ch * self.length].reshape(self.n, n_ch, self.length).transpose(1, 0, 2)
        res = np.where(w[None] > 0, res / np.where(self.weight > 0, self.weight, 1.0), 0.0)
        return res, sol, power_q

    def residuals(self, free: np.ndarray) -> np.ndarray:
        """Data residuals in units of the model error, then one weak prior row per parameter."""
        res, _, _ = self.solve(free)
        rows = [(res * self.weight)[:, self.mask].ravel() / MODEL_ERROR_K, PRIOR_WEIGHT * self.prior(free)]
        if self.per_touch:  # the touches' own contacts (and events): weak priors around the shared one (no step)
            widths = np.repeat([max(p.hi, -p.lo) for p in self.per_touch], self.n)
            rows.append(free[len(self.shared) :] / widths / TOUCH_PRIOR_SD)
        return np.concatenate(rows)

    def jacobian(self, free: np.ndarray) -> np.ndarray:
        """Forward differences (relative step 1e-5, inside the bounds): one evaluation per shared
        parameter and one per kind of per-touch parameter (a touch's own contact moves its own rows
        only, so all touches are stepped at once)."""
        hi = self.bounds()[1]
        f0 = self.residuals(free)
        k, n = len(self.shared), self.n
        jac = np.zeros((len(f0), len(free)))
        touch_of_row = np.concatenate(
            [
                np.tile(np.nonzero(self.mask)[0], 2 if self.passive else 1),
                np.full(k, -1),
                np.tile(np.arange(n), len(self.per_touch)),
            ]
        )
        groups = [[j] for j in range(k)] + [list(range(k + g * n, k + (g + 1) * n)) for g in range(len(self.per_touch))]
        for cols in groups:
            step = np.zeros_like(free)
            h = 1e-5 * np.maximum(1.0, np.abs(free[cols]))
            h = np.where(free[cols] + h > hi[cols], -h, h)
            step[cols] = h
            df = self.residuals(free + step) - f0
            if len(cols) == 1:
                jac[:, cols[0]] = df / h[0]
            else:  # column of touch i: the rows of touch i
                for i, j in enumerate(cols):
                    rows = touch_of_row == i
                    jac[rows, j] = df[rows] / h[i]
        return jac

    def prior(self, free: np.ndarray) -> np.ndarray:
        """Weak priors around the typical values (a factor of 10 for a scale, 1 s for a time): a
        parameter the data leave free stays where a sensor usually is instead of drifting to a
        bound, and two sessions of one sensor calibrate alike."""
        rows = []
        for p, v in zip(self.shared, free[: len(self.shared)], strict=True):
            width = PRIOR_LOG_SD if p.log else PRIOR_LINEAR_SD
            rows.append((v - p.to_free(p.start)) / width)
        return np.array(rows)


def calibrate_channels(
    touches: list[FitTouch],
    classes: Sequence[Sequence[Material]],
    noise: dict[str, dict[str, float]],
    *,
    starts: int = 8,
    seed: int = 0,
    heater_off: bool = True,
    nuisance: Sequence[str] = (),
    touch_contact: bool = True,
    noise_weighted: bool | None = None,
) -> CalibrationResult:
    """Multi-start fit of the model to ``touches`` (see the module docstring). ``nuisance``: the
    per-touch terms to fit, of :data:`NUISANCE_TERMS` (see
    :func:`synth.sensors.thermal.dynamics.nuisance_terms`); ``touch_contact``: after the shared
    fit, refine it jointly with every touch's own contact (conductance factor, lead, build-up)."""
    started = time.perf_counter()
    if noise_weighted is None:
        noise_weighted = NOISE_WEIGHTED
    problem = _Problem(touches, classes, heater_off, nuisance)
    lo, hi = problem.bounds()
    rng = np.random.default_rng(seed)

    run = problem.fit_from

    # multi-start: short runs from the default start and random points of the (log) box, then the
    # best one runs to convergence
    base = problem.start()
    candidates = []
    evaluations = 0
    for s in range(starts):
        x0 = base.copy()
        if s:  # around the default: far corners of the box are unphysical and slow to leave
            x0 = base + rng.normal(0.0, 1.0, len(base)) * np.minimum(1.0, 0.25 * (hi - lo))
        fit = run(x0, SHORT_RUN)
        evaluations += int(fit.nfev)
        candidates.append(fit)
    best = min(candidates, key=lambda f: f.cost)
    final = run(best.x, 200)
    evaluations += int(final.nfev)
    res, sol, power_q = problem.solve(final.x)
    values, lead, ramp = problem.unpack(final.x)
    if problem.heater_off and "heater_steps" not in problem.nuisance:
        values["heater.ambient_c"] = power_q
    spread, own_res = _touch_spread(touches, classes, heater_off, problem, final.x, noise if noise_weighted else None)
    shared_res = res
    if touch_contact:
        # the joint refinement: shared parameters and every touch's own contact together, from the
        # shared fit and the touches' own refits
        problem = problem.with_touch_contact(noise if noise_weighted else None)
        x0 = np.concatenate(
            [
                final.x,
                [math.log(r["touch_conductance_factor"]) for r in spread],
                [r["touch_lead_s"] - float(lead[0]) for r in spread],
                [math.log(r["touch_ramp_s"] / float(ramp[0])) for r in spread],
            ]
        )
        if "contact_events" in problem.nuisance:  # placed at the kinks of every touch's own-contact residual
            times, logs = place_events(problem, x0, FIT_HZ, shared=problem._event_channels() == ("both",))
            problem = problem.with_events(times).with_touch_contact(noise if noise_weighted else None)
            bound = math.log(EVENT_FACTOR_MAX) * (1 - 1e-3)
            event_x0: list[np.ndarray] = []
            for k in range(logs.shape[2]):  # per slot: each channel's log factor, then the shift (0)
                event_x0 += [np.clip(logs[c, :, k], -bound, bound) for c in range(logs.shape[0])]
                event_x0.append(np.zeros(problem.n))
            x0 = np.concatenate([x0, *event_x0])
        lo2, hi2 = problem.bounds()
        final = optimize.least_squares(
            problem.residuals,
            np.clip(x0, lo2 + 1e-9, hi2 - 1e-9),
            jac=problem.jacobian,
            bounds=(lo2, hi2),
            x_scale="jac",
            max_nfev=TOUCH_RUN,
        )
        evaluations += int(final.nfev) + int(final.njev or 0) * (problem.n_free + len(problem.per_touch))
        res, sol, power_q = problem.solve(final.x)
        values, lead, ramp = problem.unpack(final.x)
        if problem.heater_off and "heater_steps" not in problem.nuisance:
            values["heater.ambient_c"] = power_q
        own_res = res
        k = problem.n_free
        jac = np.asarray(final.jac)
        cov = np.linalg.pinv(jac.T @ jac) * float(np.mean(final.fun**2))
        for i, r in enumerate(spread):
            r["touch_conductance_factor"] = float(problem.h_scale[i])
            r["touch_conductance_sd_log"] = float(np.sqrt(max(cov[k + i, k + i], 0.0)))
            r["touch_lead_s"] = float(lead[i])
            r["touch_ramp_s"] = float(ramp[i])
    per_touch = []
    n_ch = 2 if problem.passive else 1
    for i in range(len(touches)):
        row: dict[str, float] = {"lead_s": float(lead[i]), "ramp_s": float(ramp[i]), "object_c": float(sol[i, -1])}
        row.update(spread[i])
        row["heated_onset_c"] = float(sol[i, 0])
        row["heated_drift_k_s"] = float(sol[i, 1])
        if n_ch == 2:
            row["passive_onset_c"] = float(sol[i, 2])
            row["passive_drift_k_s"] = float(sol[i, 3])
        for j, name in enumerate(problem.nuisance_columns):
            row[name] = float(sol[i, 2 * n_ch + j])
        per_touch.append(row)
    report = _report(
        problem, final, shared_res, own_res, values, per_touch, noise, evaluations, time.perf_counter() - started
    )
    if problem.per_touch:
        report["touch_contact"] = _touch_bounds(problem, final.x)
    if problem.event_t is not None:
        report["contact_events"] = _event_report(problem, final)
    return CalibrationResult(values, per_touch, {**noise.get("heated", {})}, report)


def _touch_spread(
    touches: list[FitTouch],
    classes: Sequence[Sequence[Material]],
    heater_off: bool,
    problem: _Problem,
    shared: np.ndarray,
    noise: dict[str, dict[str, float]] | None = None,
) -> tuple[list[dict[str, float]], np.ndarray]:
    """How much the touches differ: each touch refitted alone for its contact (a conductance
    factor, the lead and the build-up time), everything else at the shared fit. Their spread is
    what a calibrated scene draws from (a press is never quite the same twice). Also returns the
    residuals (C, n, W) of every touch with its own contact (0 outside its record)."""
    names = [p.name for p in problem.shared]
    i_lead, i_ramp = names.index("contact.lead_s"), names.index("contact.ramp_s")
    rows = []
    own = np.zeros((2 if problem.passive else 1, problem.n, problem.length))
    for i, tc in enumerate(touches):
        single = _Problem([tc], classes, heater_off, problem.nuisance, noise)

        def residuals(theta: np.ndarray, single: _Problem = single) -> np.ndarray:
            single.h_scale = np.array([math.exp(theta[0])])
            x = shared.copy()
            x[i_lead], x[i_ramp] = theta[1], theta[2]
            return single.residuals(x)

        lead_p, ramp_p = problem.shared[i_lead], problem.shared[i_ramp]
        lo = np.array([math.log(0.1), lead_p.to_free(lead_p.lo), ramp_p.to_free(ramp_p.lo)])
        hi = np.array([math.log(10.0), lead_p.to_free(lead_p.hi), ramp_p.to_free(ramp_p.hi)])
        x0 = np.clip(np.array([0.0, shared[i_lead], shared[i_ramp]]), lo + 1e-6, hi - 1e-6)
        fit = optimize.least_squares(residuals, x0, bounds=(lo, hi), x_scale="jac", max_nfev=40, diff_step=1e-5)
        jac = np.asarray(fit.jac)
        s2 = float(np.mean(fit.fun**2))
        # the factor's posterior s.d. (log): a wood at room temperature barely depends on H
        cov = np.linalg.pinv(jac.T @ jac) * s2
        residuals(fit.x)  # sets the touch's own conductance factor
        x_own = shared.copy()
        x_own[i_lead], x_own[i_ramp] = fit.x[1], fit.x[2]
        res_own = single.solve(x_own)[0][:, 0]
        own[:, i, : res_own.shape[1]] = res_own
        rows.append(
            {
                "touch_conductance_factor": math.exp(float(fit.x[0])),
                "touch_conductance_sd_log": float(np.sqrt(max(cov[0, 0], 0.0))),
                "touch_lead_s": float(fit.x[1]),
                "touch_ramp_s": ramp_p.from_free(float(fit.x[2])),
                "touch_rms_k": float(np.sqrt(np.mean(res_own[:, single.mask[0]] ** 2))),
            }
        )
    return rows, own


#: why a parameter sits at a bound, by (parameter, bound)
_BOUND_REASONS = {
    ("lag_share", "upper"): "one lag is enough: the second pole is faster than the samples resolve (tau_2 < 1 %)",
    ("lag_share", "lower"): "two equal lags (kept 4 % apart: equal lags are a double root)",
    ("ramp_s", "lower"): "the contact is a step at this rate: the presses are fast",
    ("off_after_onset_s", "upper"): "the heater's power changes late (1.5 s or more after the onset): a slow "
    "response, not a switch at the press (the scene puts heater = 'step' there)",
    ("off_after_onset_s", "lower"): "the heater's power changes before the onset",
    ("heat_capacity_ratio", "lower"): "the passive channel's scale is not identified (objects at its own "
    "temperature give it no signal): held at a tenth of the heated twin's",
    ("conductance_ratio", "lower"): "the passive channel's contact is not identified: held at the bound",
    ("gap_um", "upper"): "the approach passes no heat the curves show: the gap model is not asked for",
    ("gap_um", "lower"): "the gap closes to nothing: a residual gap below the contact's own resistance (k_air / H, "
    "~40 um) changes nothing the curves show, so it is not identified either; the approach speed carries the term",
    ("speed_mm_s", "upper"): "the gap closes faster than the samples resolve: the approach acts as a step at contact",
    ("speed_mm_s", "lower"): "the gap stays narrow for the whole window: the approach is a slow, flat exchange",
    ("drift_end_s", "lower"): "the contact ends the reading's drift faster than the samples resolve (a kink)",
    ("drift_end_s", "upper"): "the drift goes on through the contact: the contact does not end it",
    ("", ""): "the data push it there: the model lacks something the curves show (check the residual)",
}


def _report(
    problem: _Problem,
    fit: optimize.OptimizeResult,
    res: np.ndarray,
    own_res: np.ndarray,
    values: dict[str, float],
    per_touch: list[dict[str, float]],
    noise: dict[str, dict[str, float]],
    evaluations: int,
    seconds: float,
) -> dict[str, Any]:
    """Parameters (value, bounds, at a bound, posterior s.d.), residuals in noise sigma, and the
    parameters the data do not identify."""
    k = len(problem.shared)
    jac = np.asarray(fit.jac.toarray() if hasattr(fit.jac, "toarray") else fit.jac)[:, :k]
    dof = max(len(fit.fun) - problem.n_free, 1)
    scale2 = float((fit.fun**2).sum()) / dof
    try:
        cov = np.linalg.pinv(jac.T @ jac) * scale2
    except np.linalg.LinAlgError:  # pragma: no cover - pinv of a finite matrix converges
        cov = np.full((k, k), np.inf)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    corr = cov / np.maximum(np.outer(sd, sd), 1e-300)
    params: dict[str, Any] = {}
    at_bound, unidentified = [], []
    for j, p in enumerate(problem.shared):
        free = float(fit.x[j])
        span = p.to_free(p.hi) - p.to_free(p.lo)
        edge = None
        if free - p.to_free(p.lo) < 1e-3 * span:
            edge = "lower"
        elif p.to_free(p.hi) - free < 1e-3 * span:
            edge = "upper"
        partner = [
            problem.shared[i].name for i in range(k) if i != j and abs(corr[j, i]) > 0.99 and np.isfinite(corr[j, i])
        ]
        loose = sd[j] > (UNIDENTIFIED_LOG_SD if p.log else 0.25)
        entry: dict[str, Any] = {
            "value": values[p.name],
            "unit": p.unit,
            "bounds": [p.lo, p.hi],
            "meaning": p.doc,
            ("sd_log" if p.log else "sd"): float(sd[j]),
        }
        if edge:
            entry["at_bound"] = edge
            entry["why_at_bound"] = _BOUND_REASONS.get((p.name.split(".")[-1], edge), _BOUND_REASONS[("", "")])
            at_bound.append(p.name)
        if loose or partner:
            entry["identified"] = False
            spread = f"a factor {math.exp(min(sd[j], 700.0)):.3g}" if p.log else f"{sd[j]:.3g}"
            entry["why_not"] = f"posterior s.d. {spread}" if loose else f"correlated > 0.99 with {', '.join(partner)}"
            unidentified.append(p.name)
        params[p.name] = entry
    if "heater.ambient_c" in values:
        params["heater.ambient_c"] = {
            "value": values["heater.ambient_c"],
            "unit": "degC",
            "bounds": [None, None],
            "meaning": "the temperature the heated channel loses heat to (its heater's power is G (T - T_amb))",
        }
        if values["heater.ambient_c"] > min(r["heated_onset_c"] for r in per_touch):
            params["heater.ambient_c"]["note"] = (
                "above the heated reading: the fitted power change is a rise (more heating after the press, "
                "as a controller that goes on holding its set point adds), not a switch-off"
            )
    residual = _residual_summary(problem, own_res, noise, per_touch, "own")
    residual["shared_contact"] = _residual_summary(problem, res, noise, per_touch, "shared")
    # slope changes at a few instants (contact events no smooth model follows): how much they are
    residual["kinks"] = residual_kinks(
        own_res,
        problem.t,
        problem.mask,
        problem.onset,
        FIT_HZ,
        ("heated", "passive") if problem.passive else ("heated",),
    )
    # where the residual is in time (the contact's start, the first second, later)
    residual["windows"] = residual_windows(
        own_res, problem.t, problem.mask, problem.onset, ("heated", "passive") if problem.passive else ("heated",)
    )
    residual["contact"] = (
        "each touch with its own contact (conductance factor, lead, build-up: the touch's nuisance "
        "parameters, refitted with everything else shared); shared_contact: one contact for every touch"
    )
    return {
        "model": "lumped channel(s) + two thermistor lags + contact ramp + pre-contact drift"
        + (
            " + heater switched off after the onset"
            if problem.heater_off and "heater_steps" not in problem.nuisance
            else ""
        )
        + "".join(f" + {'' if n in _SHARED_TERMS else 'per touch: '}{_NUISANCE_DOC[n]}" for n in problem.nuisance),
        "parameters": params,
        "at_bound": at_bound,
        "not_identified": unidentified,
        "per_touch": per_touch,
        "noise": noise,
        "residual": residual,
        "solver": {
            "evaluations": evaluations,
            "seconds": seconds,
            "status": int(fit.status),
            "cost": float(fit.cost),
            # the refinement's samples weighed by 1 / their noise s.d. (else all alike, in K)
            "noise_weighted": bool(problem.noise_weighted),
        },
    }


def _residual_summary(
    problem: _Problem,
    res: np.ndarray,
    noise: dict[str, dict[str, float]],
    per_touch: list[dict[str, float]],
    tag: str,
) -> dict[str, Any]:
    """Residuals ``res`` (C, n, W) per channel and overall: RMS in K and in noise sigma, two ways:

    - ``rms_sigma``: against ``sigma(t)^2 = sigma_w^2 + (sigma_t dx/dt)^2`` (white noise from a
      0.25 s spline's remainder before the onset, timing jitter; see :func:`noise_levels`);
    - ``rms_sigma_precontact``: ``sigma_w`` replaced by the pre-contact segment's scatter about a
      quadratic trend at the recorder's rate (``precontact_k``): the correlated noise's own
      variance at every time scale up to the segment's length (~0.4 s), which the spline's knots
      would partly follow.

    Both compare a per-sample RMS with a per-sample variance: a correlated noise has the same
    variance per sample, it only gives the residual fewer independent samples. Each touch's row
    gets ``<channel>_rms_k`` (tag ``shared``) or ``<channel>_own_rms_k`` (tag ``own``)."""
    channels = ("heated", "passive") if problem.passive else ("heated",)
    out: dict[str, Any] = {}
    total_k, total_z, total_zp = [], [], []
    for c, ch in enumerate(channels):
        nz = noise.get(ch, {"white_k": 1e-3, "timing_jitter_s": 0.0})
        fitted = problem.x[c] + res[c]  # the model's curve
        jitter = nz["timing_jitter_s"] * np.gradient(fitted, axis=1) * FIT_HZ
        sigma = np.sqrt(nz["white_k"] ** 2 + jitter**2)
        sigma_pre = np.sqrt(nz.get("precontact_k", nz["white_k"]) ** 2 + jitter**2)
        r = res[c][problem.mask]
        z = (res[c] / sigma)[problem.mask]
        zp = (res[c] / sigma_pre)[problem.mask]
        total_k.append(r)
        total_z.append(z)
        total_zp.append(zp)
        out[ch] = {
            "rms_k": float(np.sqrt(np.mean(r**2))),
            "rms_sigma": float(np.sqrt(np.mean(z**2))),
            "rms_sigma_precontact": float(np.sqrt(np.mean(zp**2))),
        }
        key = f"{ch}_rms_k" if tag == "shared" else f"{ch}_own_rms_k"
        for i, row in enumerate(per_touch):
            row[key] = float(np.sqrt(np.mean(res[c, i][problem.mask[i]] ** 2)))
    rms_sigma = float(np.sqrt(np.mean(np.concatenate(total_z) ** 2)))
    return {
        **out,
        "rms_k": float(np.sqrt(np.mean(np.concatenate(total_k) ** 2))),
        "rms_sigma": rms_sigma,
        "rms_sigma_precontact": float(np.sqrt(np.mean(np.concatenate(total_zp) ** 2))),
        "within_3_sigma": rms_sigma <= 3.0,
    }


def _event_report(problem: _Problem, fit: optimize.OptimizeResult) -> dict[str, Any]:
    """Every contact event: its touch, time, each channel's conductance factor with its posterior
    s.d. (log) and whether it sits at a bound; how many factors sit at a bound."""
    events = problem.events(fit.x)
    assert problem.event_t is not None
    times, factors = events if events is not None else (problem.event_t, np.ones((1, *problem.event_t.shape)))
    jac = np.asarray(fit.jac)
    cov = np.linalg.pinv(jac.T @ jac) * float(np.mean(fit.fun**2))
    names = [p.name for p in problem.per_touch]
    channels = problem._event_channels()
    bound = math.log(EVENT_FACTOR_MAX)
    rows, at_bound = [], 0
    for i in range(problem.n):
        for k in np.flatnonzero(np.isfinite(problem.event_t[i])):
            # the recording's file name only (a report goes into a model card: no path of this machine)
            row: dict[str, Any] = {"touch": Path(problem.touches[i].file).name, "t_s": float(times[i, k])}
            for c, ch in enumerate(channels):
                col = problem.n_free + names.index(f"event{k}.{ch}_log_factor") * problem.n + i
                log_f = math.log(float(factors[c, i, k]))
                row[f"{ch}_factor"] = float(factors[c, i, k])
                row[f"{ch}_sd_log"] = float(np.sqrt(max(cov[col, col], 0.0)))
                if bound - abs(log_f) < 1e-3 * 2 * bound:  # within 1e-3 of the span, as the other parameters
                    row[f"{ch}_at_bound"] = True
                    at_bound += 1
            rows.append(row)
    return {
        "events": rows,
        "count": len(rows),
        "factor_bounds": [1.0 / EVENT_FACTOR_MAX, EVENT_FACTOR_MAX],
        "factors_at_bound": at_bound,
        "why_at_bound": "a step the fit would make larger than twofold: what the residual holds there is more than a "
        "change of the contact conductance (the kinks are sharper than a step behind the thermistor's lags can bend "
        "the reading)"
        if at_bound
        else None,
        "meaning": "the contact conductance of each channel times the factor from the event's time on (slip or "
        "creep of the pad while the force holds); events found at the kinks of the own-contact residual",
    }


def _touch_bounds(problem: _Problem, free: np.ndarray) -> dict[str, Any]:
    """Every touch's own contact: how many touches sit at a bound of each parameter, and why."""
    lo, hi = problem.bounds()
    k, n = problem.n_free, problem.n
    out: dict[str, Any] = {}
    for g, p in enumerate(problem.per_touch):
        if p.name.startswith("event"):  # reported with the events (contact_events)
            continue
        cols = slice(k + g * n, k + (g + 1) * n)
        span = hi[cols] - lo[cols]
        low = int(np.sum(free[cols] - lo[cols] < 1e-3 * span))
        high = int(np.sum(hi[cols] - free[cols] < 1e-3 * span))
        out[p.name] = {"bounds": [p.lo, p.hi], "meaning": p.doc, "touches_at_lower": low, "touches_at_upper": high}
        if low or high:
            out[p.name]["why_at_bound"] = (
                "a touch whose curve hardly depends on it (a wood at the sensor's own temperature barely "
                "depends on its contact) drifts to the bound; its prior keeps the rest near the shared value"
                if "conductance" in p.name
                else "the touch's curve asks for a contact further from the shared one than the bound allows: "
                "the model lacks something at the press (see the residual)"
            )
    return out
