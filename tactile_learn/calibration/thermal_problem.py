"""The thermal calibration's least-squares problem over a batch of labelled touches.

:class:`CalibrationProblem` holds the touches on a common grid and evaluates the model of
:mod:`.thermal_calibration` for a vector of free parameters (:mod:`.thermal_parameters`): the design
columns of every channel, the linear values solved exactly inside every evaluation (variable
projection, with the shared ambient), the residuals with their weak priors and a Jacobian that steps
every touch's own parameters at once. :func:`~.thermal_calibration.calibrate_channels` drives it.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy import optimize

from synth.materials import Material
from synth.sensors.thermal.approach import approach_term
from synth.sensors.thermal.contact_events import contact_event_terms
from synth.sensors.thermal.dynamics import ChannelModel, channel_terms, nuisance_terms
from synth.sensors.thermal.readout import drift_ending_at_contact
from tactile_learn.calibration.thermal_parameters import (
    APPROACH_HZ,
    APPROACH_WINDOW_S,
    DRIFT_ENDS_CHANNELS,
    DRIFT_PRIOR_K_S,
    EVENT_HZ,
    MODEL_ERROR_K,
    NUISANCE_TERMS,
    OBJECT_PRIOR_K,
    PRECURSOR_S,
    PRIOR_LINEAR_SD,
    PRIOR_LOG_SD,
    PRIOR_ROW_K,
    PRIOR_ROW_TOUCH_K,
    PRIOR_WEIGHT,
    TOUCH_CONTACT_PARAMETERS,
    TOUCH_PRIOR_SD,
    TWIN_RATIOS,
    Parameter,
    event_factor_channels,
    event_parameters,
    shared_parameters,
    twin_ratio_name,
)
from tactile_learn.calibration.thermal_touches import FIT_HZ, FitTouch

__all__ = ["CalibrationProblem"]


def _class_nominal(materials: Sequence[Material]) -> tuple[float, float]:
    """A class's effusivity and diffusivity (m^2/s): geometric means over its library materials."""
    e = math.exp(float(np.mean([math.log(m.effusivity) for m in materials])))
    alpha = math.exp(float(np.mean([math.log(m.diffusivity_mm2_s * 1e-6) for m in materials])))
    return e, alpha


class CalibrationProblem:
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
        #: the joint refinement fits in noise units (see thermal_calibration.NOISE_WEIGHTED)
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
        # the temperatures identify only e / C, G / C, H / C: each class's effusivity is fixed at its
        # library value (the geometric mean over its materials), which sets the scale of C
        self.class_e = np.array([_class_nominal(mats)[0] for mats in classes])
        self.class_alpha = np.array([_class_nominal(mats)[1] for mats in classes])
        self.shared = shared_parameters(self.passive, heater_off, "approach" in self.nuisance, self.drift_end_channels)
        self.per_touch: list[Parameter] = []
        #: per-touch contact quality: every channel's H times this (1 in the shared fit)
        self.h_scale = np.ones(self.n)
        #: the linear priors' row scale (see PRIOR_ROW_K)
        self.prior_row_k = PRIOR_ROW_K
        #: contact events' times (n, K) after each onset (NaN: none), set by with_events
        self.event_t: np.ndarray | None = None

    def _noise_weights(self, noise: dict[str, dict[str, float]] | None) -> np.ndarray:
        """1 / sigma(t) of every sample, ``sigma^2 = sigma_w^2 + (sigma_t dx/dt)^2`` with the data's
        own slope (the noise model of :func:`~.thermal_touches.noise_levels`, the unit the report's
        residual is given in: a fit in that unit is the maximum-likelihood one), normalised to a mean
        square of 1 over the samples (the residual rows keep their scale against the priors); 1
        without ``noise``."""
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

    def with_events(self, times: Sequence[Sequence[float]]) -> CalibrationProblem:
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
        return event_parameters(self.event_t.shape[1], self.event_channels())

    def event_channels(self) -> tuple[str, ...]:
        """Whose factor an event has: each channel's, or one for both (EVENT_FACTOR_SHARED)."""
        return event_factor_channels(self.passive)

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
        channels = self.event_channels()
        factors = np.exp(
            np.stack([np.stack([values(f"event{k}.{ch}_log_factor") for k in slots], axis=1) for ch in channels])
        )
        if channels == ("both",):
            factors = np.concatenate([factors, factors])
        return times, factors

    def with_touch_contact(self, noise: dict[str, dict[str, float]] | None = None) -> CalibrationProblem:
        """The same problem with every touch's own contact (free, after the shared fit): its
        conductance factor, its lead and its build-up time relative to the shared ones, each with a
        weak prior (they trade off with the shared contact)."""
        twin = copy.copy(self)
        twin.per_touch = list(TOUCH_CONTACT_PARAMETERS) + self._event_parameters()
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
        for name in TWIN_RATIOS:
            ratio = twin_ratio_name(name)
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
