"""Calibration of a seed-like thermal fingertip (one heated thermistor, a step contact) from touches
of known materials: the sensor's own heat capacity, loss and contact radius.

:func:`calibrate_sensor` fits, with ``scipy.optimize.least_squares``, the contact model of
:mod:`~tactile_learn.estimators.classical.physics_fit` to every touch at once: shared ``C``, ``G``,
contact radius; per touch its conductance, amplitude, onset and baseline (a real fingertip with
lags, heater control and a passive channel: :mod:`tactile_learn.calibration.thermal_calibration`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from synth.errors import DataError
from synth.materials import Material, get_material
from synth.sensors.thermal import ThermalConfig, spreading_conductance
from tactile_learn.estimators.classical.curve_match import nominal_sensor
from tactile_learn.estimators.classical.physics_fit import contact_drop, material_gaussians
from tactile_learn.thermal_signal import detect_onset

if TYPE_CHECKING:
    from tactile_learn.thermal_recordings import Touch

__all__ = ["calibrate_sensor"]


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

    if not touches:
        raise DataError("calibration needs at least one labelled touch")
    fs = float(np.median([t.sampling_hz for t in touches]))
    step = _adc_step(touches)
    series = _touch_series(touches, fs, step, fit_s)
    c0, g0 = nominal_sensor(config)
    r0 = math.sqrt(config.contact.radius_mm[0] * config.contact.radius_mm[1]) * 1e-3
    h_mid = math.sqrt(config.contact.conductance_w_m2k[0] * config.contact.conductance_w_m2k[1])
    spreading = config.contact.spreading
    # parameter vector: log C, log G, log a, then per touch (b, V0, log H, t0, log e)
    gauss = material_gaussians([s[2] for s in series])
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
            f = contact_drop(
                t[None, :], np.array([c]), np.array([g]), np.array([e]), np.array([math.exp(lh)]), np.array([ks])
            )[0]
            out.append((values - (b - v0 * f)) / sigma[i])
            out.append(np.array([(lh - math.log(h_mid)) / (2 * prior_h)]))  # weak: H alone is poorly set
            out.append(np.array([(le - gauss[i, 0]) / gauss[i, 1]]))
        return np.concatenate(out)

    fit = least_squares(residuals, np.array(p0), bounds=(np.array(lo), np.array(hi)), x_scale="jac", max_nfev=400)
    return _calibrated_config(config, fit, fs, step, float(np.median(sigma)))


def _touch_series(
    touches: Sequence[Touch], fs: float, step: float, fit_s: float
) -> list[tuple[np.ndarray, float, Material, float, float]]:
    """Every touch resampled to ``fs`` up to ``fit_s`` of contact (or its release): its values,
    onset (s), material, noise (K) and baseline."""
    from tactile_learn.thermal_recordings import resample

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
    return series


def _calibrated_config(
    config: ThermalConfig, fit: Any, fs: float, step: float, noise: float
) -> tuple[ThermalConfig, dict[str, Any]]:
    """The calibrated config (the fitted sensor with a small spread, the user's readout) and the
    summary, from the solver's result ``fit`` over (log C, log G, log a, then per touch b, V0,
    log H, t0, log e)."""
    p = fit.x
    c_fit, g_fit, a_fit = (math.exp(v) for v in p[:3])
    per = p[3:].reshape(-1, 5)
    h_fit = np.exp(per[:, 2])
    v0_fit = per[:, 1]
    baseline = per[:, 0]
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
