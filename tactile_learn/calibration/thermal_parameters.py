"""The thermal calibration's parameters (name, unit, bounds, start, meaning) and the fit's settings.

:func:`shared_parameters` lists what a calibration problem fits for every touch alike (each
channel's lumped model, the contact, the heater's power change and the opt-in shared terms);
:data:`TOUCH_CONTACT_PARAMETERS` and :func:`event_parameters` what the joint refinement fits per
touch. The model they parametrise: :mod:`.thermal_calibration`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = [
    "NUISANCE_TERMS",
    "TOUCH_CONTACT_PARAMETERS",
    "Parameter",
    "event_factor_channels",
    "event_parameters",
    "shared_parameters",
    "twin_ratio_name",
]

#: the contact starts at most this long before the onset
LEAD_MAX_S = 1.5
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
SHARED_TERMS = ("approach", "drift_ends")
NUISANCE_DOC = {
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


CHANNEL_PARAMETERS = (
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
TWIN_RATIOS = {"heat_capacity_j_m2k": (0.1, 10.0, 0.5), "conductance_w_m2k": (0.05, 10.0, 0.5)}


#: every touch's own contact (relative to the shared one): log conductance factor, lead offset (s),
#: log build-up factor; ``hi`` is also the s.d. of its weak prior (in TOUCH_PRIOR_SD units)
TOUCH_CONTACT_PARAMETERS = (
    Parameter("touch.log_conductance_factor", "", -math.log(10.0), math.log(10.0), 0.0, False, "log H factor"),
    Parameter("touch.lead_offset_s", "s", -0.5, 0.5, 0.0, False, "contact start relative to the shared lead"),
    Parameter("touch.log_ramp_factor", "", -math.log(30.0), math.log(30.0), 0.0, False, "log build-up factor"),
)
#: the touches' own contacts' prior s.d., as a fraction of their bounds
TOUCH_PRIOR_SD = 0.5


def twin_ratio_name(name: str) -> str:
    """The passive channel's parameter for ``name`` of :data:`TWIN_RATIOS`: its ratio to the heated twin's."""
    return name.replace("_j_m2k", "").replace("_w_m2k", "") + "_ratio"


def shared_parameters(
    passive: bool, heater_off: bool, approach: bool, drift_end_channels: Sequence[str]
) -> list[Parameter]:
    """The parameters every touch shares, in the order of the problem's free vector: each
    channel's lumped model (the passive one's scale as ratios to the heated twin's), the contact,
    the heater's power change (``heater_off``), the approach's gap and speed (``approach``) and the
    drift's end lag of ``drift_end_channels``."""
    params: list[Parameter] = []
    channels = ("heated", "passive") if passive else ("heated",)
    for ch in channels:
        for name, unit, lo, hi, start, doc in CHANNEL_PARAMETERS:
            log = name != "lag_share"
            if ch == "passive" and name in TWIN_RATIOS:
                # a passive thermistor's scale is hardly seen (objects at its own temperature give
                # it no signal): its C and H are held within a factor of the heated twin's
                r_lo, r_hi, r_start = TWIN_RATIOS[name]
                doc = f"{doc}, relative to the heated channel's"
                params.append(Parameter(f"passive.{twin_ratio_name(name)}", "", r_lo, r_hi, r_start, True, doc))
                continue
            first = start if ch == "heated" or not log else start / 4
            params.append(Parameter(f"{ch}.{name}", unit, lo, hi, first, log, doc))
    params.append(Parameter("contact.radius_mm", "mm", 0.1, 50.0, 5.0, True, "contact patch radius a"))
    params.append(Parameter("contact.lead_s", "s", -0.3, LEAD_MAX_S, 0.1, False, "contact start before the onset"))
    params.append(Parameter("contact.ramp_s", "s", 0.02, 2.0, 0.1, True, "contact build-up time"))
    if heater_off:
        params.append(
            Parameter("heater.off_after_onset_s", "s", -1.5, 1.5, 0.0, False, "time of the heater's power change")
        )
    if approach:
        # physical ranges: a residual gap from a polished to a rough, tilted pad; a robot's slow
        # final approach (mm/s)
        params.append(Parameter("approach.gap_um", "um", 1.0, 3000.0, 200.0, True, "residual air gap g0 at contact"))
        params.append(Parameter("approach.speed_mm_s", "mm/s", 0.1, 50.0, 2.0, True, "approach speed v"))
    for ch in drift_end_channels:
        doc = "lag with which the contact ends the reading's pre-contact drift"
        params.append(Parameter(f"{ch}.drift_end_s", "s", *DRIFT_END_S, 0.3, True, doc))
    return params


def event_factor_channels(passive: bool) -> tuple[str, ...]:
    """Whose factor a contact event has: each channel's, or one for both (EVENT_FACTOR_SHARED)."""
    if EVENT_FACTOR_SHARED and passive:
        return ("both",)
    return ("heated", "passive") if passive else ("heated",)


def event_parameters(slots: int, channels: Sequence[str]) -> list[Parameter]:
    """Per event slot: each of ``channels``' log conductance factor and the time shift (see EVENT_*)."""
    bound = math.log(EVENT_FACTOR_MAX)
    out = []
    for k in range(slots):
        for ch in channels:
            doc = f"log of the {ch} contact conductance factor at the touch's event {k}"
            out.append(Parameter(f"event{k}.{ch}_log_factor", "", -bound, bound, 0.0, False, doc))
        doc = f"shift of event {k}'s time from the kink's"
        out.append(Parameter(f"event{k}.shift_s", "s", *EVENT_SHIFT_S, 0.0, False, doc))
    return out
