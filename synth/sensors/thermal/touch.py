"""Touches of a real thermal fingertip: lagging thermistors, a controlled heater, a passive channel.

The seed's model (:mod:`synth.sensors.thermal`) has a heated pixel at its open-loop steady state
and a step contact. A real fingertip (e.g. the robot recordings of issue 11) differs: its
thermistors lag the body they sit in, its heater is held at a set point (or switched off when the
press is detected), its reading drifts before contact, the contact builds up over the press, a
passive (unheated) thermistor touches the same object, and the recorder jitters its time stamps.
Every one of these is a term of the closed form of :func:`synth.sensors.thermal.dynamics.channel_terms`
(verified against a finite-volume solution in the tests); per pixel in contact::

    heated  = R0 + r drift(t) + (R0 + r (tau_1 + tau_2) - T_obj) obj(t) - Q power(t - t_off)   [heater "off"]
    passive = P0 + r_p drift_p(t) + (P0 + r_p (tau_1p + tau_2p) - T_obj) obj_p(t),   r_p = drift + approach (T_obj - P0)

``R0`` is the heated reading before contact (``T_amb + Q/G`` open loop, the set point otherwise),
``Q`` the heater's power when it switches off (``heater_w_m2``, heater ``off``; heater ``step``:
``-Q`` is ``heater_step_w_m2``, a change of either sign), ``P0 =
T_amb + offset`` the passive reading; both channels share the object's temperature ``T_obj`` and
the contact's onset and build-up ``ramp_s``. Time-stamp jitter ``dt ~ N(0, timing_jitter_s)`` moves
each sample by ``slope * dt``. The touch lasts to the end of the record (release is not modelled
here; :class:`~synth.sensors.thermal.ThermalConfig` checks that). Pixels touching nothing read
``R0 + r t`` (heated) and ``P0 + r_p t`` (passive), ``t`` from the onset.
"""

from __future__ import annotations

import numpy as np

from synth.sensors.thermal.config import ThermalConfig
from synth.sensors.thermal.dynamics import ChannelModel, channel_terms

__all__ = ["clean_channels", "draw_dynamics", "jitter"]


def draw_dynamics(config: ThermalConfig, n: int, p: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """The real-sensor quantities of ``n`` touches of ``p`` pixels (float64), drawn after the
    seed's, so scenes without them draw the same stream as before."""
    sc, cc, pc = config.sensor, config.contact, config.passive

    def uni(bounds: tuple[float, float], shape: tuple[int, ...]) -> np.ndarray:
        return rng.uniform(bounds[0], bounds[1], size=shape)

    def log_uni(bounds: tuple[float, float], shape: tuple[int, ...]) -> np.ndarray:
        return np.exp(rng.uniform(np.log(bounds[0]), np.log(bounds[1]), size=shape))

    out = {
        "lag1": np.broadcast_to(uni(sc.lag_s, (n, 1)), (n, p)).copy(),
        "lag2": np.broadcast_to(uni(sc.lag2_s, (n, 1)), (n, p)).copy(),
        "set_point": np.broadcast_to(uni(sc.set_point_c, (n, 1)), (n, p)).copy(),
        "kp": np.broadcast_to(uni(sc.controller_kp, (n, 1)), (n, p)).copy(),
        "ki": np.broadcast_to(uni(sc.controller_ki, (n, 1)), (n, p)).copy(),
        "heater_off": np.broadcast_to(uni(sc.heater_off_s, (n, 1)), (n, p)).copy(),
        "heater_step": np.broadcast_to(uni(sc.heater_step_w_m2, (n, 1)), (n, p)).copy(),
        "drift": np.broadcast_to(uni(sc.drift_k_s, (n, 1)), (n, p)).copy(),
        "ramp": np.broadcast_to(uni(cc.ramp_s, (n, 1)), (n, p)).copy(),
    }
    if pc.enabled:
        out.update(
            p_heat_capacity=np.broadcast_to(uni(pc.heat_capacity_j_m2k, (n, 1)), (n, p)).copy(),
            p_loss=np.broadcast_to(uni(pc.loss_w_m2k, (n, 1)), (n, p)).copy(),
            p_conductance=log_uni(pc.conductance_w_m2k, (n, 1)) * np.ones((1, p)),
            p_lag1=np.broadcast_to(uni(pc.lag_s, (n, 1)), (n, p)).copy(),
            p_lag2=np.broadcast_to(uni(pc.lag2_s, (n, 1)), (n, p)).copy(),
            p_offset=np.broadcast_to(uni(pc.offset_k, (n, 1)), (n, p)).copy(),
            p_drift=np.broadcast_to(uni(pc.drift_k_s, (n, 1)), (n, p)).copy(),
            p_approach=np.broadcast_to(uni(pc.approach_per_s, (n, 1)), (n, p)).copy(),
        )
    return out


def clean_channels(
    config: ThermalConfig, time_s: np.ndarray, d: dict[str, np.ndarray]
) -> tuple[np.ndarray, np.ndarray | None]:
    """Noise-free heated and passive readings (n, P, R) in degC of the touches ``d`` (the seed's
    draws plus :func:`draw_dynamics`'), float64; passive is ``None`` when disabled."""
    n, p = d["touched"].shape
    sc = config.sensor
    t_rel = time_s[None, None, :] - d["onset"][..., None]  # (n, P, R)
    ambient = np.broadcast_to(d["ambient"][:, None], (n, p))
    # open loop: the seed's steady state above ambient; otherwise the set point the heater held
    start = ambient + d["heater"] / d["loss"] if sc.heater == "open" else d["set_point"]
    drift = d["drift"]
    heated = start[..., None] + drift[..., None] * t_rel  # pixels touching nothing keep drifting
    passive = None
    if config.passive.enabled:
        p_start = ambient + d["p_offset"]
        # the approach to the object: a drift towards it (pixels touching nothing: no object)
        p_drift = d["p_drift"] + np.where(d["touched"], d["p_approach"] * (d["object_c"] - p_start), 0.0)
        passive = p_start[..., None] + p_drift[..., None] * t_rel
    sel = d["touched"]
    if not sel.any():
        return heated, passive
    t_sel = t_rel[sel]
    lag1, lag2 = d["lag1"][sel], d["lag2"][sel]
    model = ChannelModel.create(
        heat_capacity=d["heat_capacity"][sel],
        loss=d["loss"][sel],
        conductance=d["conductance"][sel],
        effusivity=d["effusivity"][sel],
        spreading=d["spreading"][sel],
        lag1_s=lag1,
        lag2_s=lag2,
        kp=d["kp"][sel],
        ki=d["ki"][sel],
    )
    t_off = d["heater_off"][sel] if sc.heater in ("off", "step") else None
    terms = channel_terms(model, t_sel, d["ramp"][sel], t_off)
    r0, r, obj_c = start[sel], drift[sel], d["object_c"][sel]
    v0 = r0 + r * (lag1 + lag2) - obj_c
    if sc.heater == "held":  # a controlled channel rests at its set point: no drift term
        curve = r0[:, None] + v0[:, None] * terms.obj
    else:
        curve = r0[:, None] + r[:, None] * terms.drift + v0[:, None] * terms.obj
    if terms.power is not None:  # at t_off the heater's power drops to 0 (off) or changes (step)
        change = -d["heater"][sel] if sc.heater == "off" else d["heater_step"][sel]
        curve += change[:, None] * terms.power
    heated[sel] = curve
    if passive is not None:
        p_model = ChannelModel.create(
            heat_capacity=d["p_heat_capacity"][sel],
            loss=d["p_loss"][sel],
            conductance=d["p_conductance"][sel],
            effusivity=d["effusivity"][sel],
            spreading=d["spreading"][sel],
            lag1_s=d["p_lag1"][sel],
            lag2_s=d["p_lag2"][sel],
        )
        p_terms = channel_terms(p_model, t_sel, d["ramp"][sel])
        p0, rp = p_start[sel], p_drift[sel]
        pv0 = p0 + rp * (d["p_lag1"][sel] + d["p_lag2"][sel]) - obj_c
        passive[sel] = p0[:, None] + rp[:, None] * p_terms.drift + pv0[:, None] * p_terms.obj
    return heated, passive


def jitter(clean: np.ndarray, time_s: np.ndarray, sigma_s: float, rng: np.random.Generator) -> np.ndarray:
    """``clean`` (..., R) sampled at time stamps off by ``N(0, sigma_s)`` each: ``+ slope * dt``."""
    if sigma_s <= 0 or clean.shape[-1] < 2:
        return clean
    slope = np.gradient(clean, time_s, axis=-1)
    return clean + slope * (sigma_s * rng.standard_normal(clean.shape))
