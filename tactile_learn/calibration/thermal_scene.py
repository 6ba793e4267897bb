"""From a user's labelled recordings to a scene of their sensor (the calibration of a real fingertip).

:func:`calibrate_recordings`: the labels become the scene's classes (materials, families or the
user's own classes), every labelled touch's onset is found (force, else the curve), the noise is
measured, and :func:`~tactile_learn.calibration.thermal_calibration.calibrate_channels` fits the
sensor; the fitted values, widened a little (a sensor drifts from day to day, and a model that
explains the curves to a few hundredths of a kelvin should not train a network on one exact shape),
become a scene whose objects' temperatures are unknown over a wide range (cooled and warmed
objects). The scene is validated (it must load back) before it is written, atomically
(:func:`write_scene`). The workflow that goes on to a classifier is :mod:`tactile_learn.thermal_adapt`.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from synth.config import dumps_toml
from synth.errors import ConfigError, DataError
from synth.io import atomic_write_text
from synth.materials import resolve_label
from synth.scene import Scene, parse_scene
from synth.sensors.thermal import (
    ContactConfig,
    ObjectClass,
    ObjectsConfig,
    PassiveConfig,
    ReadoutConfig,
    SensorConfig,
    ThermalConfig,
)
from tactile_learn.calibration.thermal_calibration import (
    FIT_HZ,
    CalibrationResult,
    calibrate_channels,
    noise_levels,
    prepare_touches,
)
from tactile_learn.thermal_recordings import Touch, read_recordings, resample
from tactile_learn.thermal_signal import onset_seconds, press_onset

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = ["CHANNEL_CHOICES", "calibrate_recordings", "scene_from_fit", "write_scene"]

#: --channels values: the classifier's input channels
CHANNEL_CHOICES = {"heated": ("heated",), "all": ("heated", "passive")}
#: classifier input window and rate of a calibrated scene
WINDOW_S = 6.0
RECORD_S = 9.0
#: object temperature minus ambient (K) that a calibrated scene covers at least
OBJECT_SPAN_K = (-12.0, 12.0)


def _onset(touch: Touch) -> tuple[float, str]:
    """The touch's onset (record time) and where it came from."""
    if touch.onset_s is not None:
        return touch.onset_s, "given"
    if touch.force is not None:
        pressed = press_onset(touch.time_s, touch.force)
        if pressed is not None:
            return pressed, "force"
    fs = touch.sampling_hz
    values, _ = resample(touch, fs)
    onset_s, detected = onset_seconds(values[None, :], fs)
    if not detected[0]:
        raise DataError(f"{touch.file}: no contact found (no force column, and the curve shows no departure)")
    return float(touch.time_s[0]) + float(onset_s[0]), "curve"


def _classes(touches: list[Touch], class_map: dict[str, tuple[str, ...]] | None) -> list[tuple[str, tuple[str, ...]]]:
    """The user's classes in order of first appearance: (name, the library materials it stands for)."""
    out: dict[str, tuple[str, ...]] = {}
    for t in touches:
        if t.material and t.material not in out:
            out[t.material] = tuple(m.name for m in resolve_label(t.material, class_map))
    if len(out) < 2:
        raise DataError(
            f"the labelled touches name {len(out)} class(es) ({', '.join(out)}): a classifier needs two or more"
        )
    seen: dict[str, str] = {}
    for name, mats in out.items():
        for m in mats:
            if m in seen:
                raise DataError(
                    f"classes {seen[m]!r} and {name!r} both contain {m!r}: give disjoint classes (--classes FILE.toml)"
                )
            seen[m] = name
    return sorted(out.items())


def calibrate_recordings(
    source: str | Path,
    channels: tuple[str, ...] = ("heated", "passive"),
    class_map: dict[str, tuple[str, ...]] | None = None,
    *,
    starts: int = 6,
    seed: int = 0,
    name: str = "calibrated",
    nuisance: tuple[str, ...] | None = None,
    noise_weighted: bool | None = None,
) -> tuple[Scene, dict[str, Any]]:
    """Fit the user's sensor from the labelled touches in ``source``; returns the scene and the
    calibration report (see the module docstring). The passive channel is fitted whenever every
    touch has one (it pins the object's temperature), whatever ``channels`` the scene's classifier
    will read. ``nuisance``: the per-touch nuisance terms to fit (default: the calibration's;
    see :data:`~tactile_learn.calibration.thermal_calibration.NUISANCE_TERMS`); ``noise_weighted``: refine in
    noise units (default: the calibration's, see its ``NOISE_WEIGHTED``)."""
    touches = [t for t in read_recordings(source, class_map=class_map) if t.material]
    if len(touches) < 2:
        raise DataError(f"{source}: {len(touches)} labelled touch(es): calibration needs two or more")
    classes = _classes(touches, class_map)
    names = [c[0] for c in classes]
    has_passive = all(t.passive_c is not None for t in touches)
    if "passive" in channels and not has_passive:
        raise DataError(f"{source}: --channels all needs a passive_c column in every touch file")
    from synth.materials import get_material

    series, heated_noise, passive_noise, origin = [], [], [], []
    for t in touches:
        onset, how = _onset(t)
        origin.append(how)
        passive = t.passive_c if has_passive else None
        series.append((t.file, names.index(str(t.material)), t.time_s, t.temperature_c, passive, onset))
        heated_noise.append((t.time_s, t.temperature_c, onset))
        if passive is not None:
            passive_noise.append((t.time_s, passive, onset))
    noise = {"heated": noise_levels(heated_noise)}
    if has_passive:
        noise["passive"] = noise_levels(passive_noise)
    fit_touches = prepare_touches(series)
    materials = [[get_material(m) for m in mats] for _, mats in classes]
    result = calibrate_channels(
        fit_touches,
        materials,
        noise,
        starts=starts,
        seed=seed,
        noise_weighted=noise_weighted,
        nuisance=() if nuisance is None else nuisance,
    )
    scene = scene_from_fit(result, classes, channels, noise, name=name)
    report = dict(result.report)
    report["classes"] = {n: list(m) for n, m in classes}
    # the recording's file name only: the report goes into a model card, which never records a
    # path of the machine it was made on (a labelled folder may also be a temporary selection)
    report["touches"] = [
        {"file": Path(t.file).name, "label": t.material, "onset_from": how, **row}
        for t, how, row in zip(touches, origin, report.pop("per_touch"), strict=True)
    ]
    report["channels_fitted"] = ["heated", "passive"] if has_passive else ["heated"]
    return scene, report


def _around(value: float, rel: float, lo: float = 0.0) -> tuple[float, float]:
    return (max(value * (1 - rel), lo), max(value * (1 + rel), lo))


def _span(values: list[float], pad: float) -> tuple[float, float]:
    return (round(min(values) - pad, 6), round(max(values) + pad, 6))


def scene_from_fit(
    result: CalibrationResult,
    classes: list[tuple[str, tuple[str, ...]]],
    channels: tuple[str, ...],
    noise: dict[str, dict[str, float]],
    name: str = "calibrated",
) -> Scene:
    """The calibrated scene (fitted values widened: see the module docstring); validated."""
    v = result.values
    rows = result.report["per_touch"]
    has_passive = "passive.heat_capacity_j_m2k" in v
    ambient_values = [r["passive_onset_c"] for r in rows] if has_passive else [v.get("heater.ambient_c", 22.0)]
    sensor = _sensor_config(v, rows, ambient_values)
    # the touches' own spread (each refitted alone for its contact), widened by a fifth
    h = v["heated.conductance_w_m2k"]
    # only touches whose curve pins their contact count (H hardly shapes a low-effusivity object at
    # the sensor's own temperature: its factor is uncertain by 10 % or more); none: a factor 1.25 either way
    factors = [r["touch_conductance_factor"] for r in rows if r["touch_conductance_sd_log"] < 0.1] or [1 / 1.25, 1.25]
    h_range = (h * min(factors) / 1.2, h * max(factors) * 1.2)
    radius = v["contact.radius_mm"]
    contact = ContactConfig(
        conductance_w_m2k=h_range,
        pixel_conductance_spread=0.0,
        radius_mm=(max(radius / 1.5, 0.1), min(radius * 1.5, 1000.0)),
        spreading=True,
        onset_s=(2.5, 3.5),
        onset_jitter_s=0.0,
        contact_s=(RECORD_S, RECORD_S),
        ramp_s=(0.0, 1.5 * max(r["touch_ramp_s"] for r in rows) + 0.1),
    )
    offsets = [r["object_c"] - float(np.mean(ambient_values)) for r in rows]
    objects = ObjectsConfig(
        classes=tuple(ObjectClass(name=n, materials=m) for n, m in classes),
        offset_k=(min(OBJECT_SPAN_K[0], min(offsets) - 5.0), max(OBJECT_SPAN_K[1], max(offsets) + 5.0)),
        second_object=0.0,
        property_spread=1.0,
    )
    passive = _passive_config(v, rows, factors) if has_passive else PassiveConfig()
    readout = ReadoutConfig(
        sampling_hz=FIT_HZ,
        duration_s=RECORD_S,
        noise_k=round(max(noise["heated"]["white_k"], 1e-4), 6),
        adc_step_k=0.0,
        adc_range_c=(-50.0, 150.0),
        timing_jitter_s=round(noise["heated"]["timing_jitter_s"], 6),
    )
    config = ThermalConfig(
        grid=(1, 1),
        window_s=WINDOW_S,
        sensor=sensor,
        contact=contact,
        objects=objects,
        readout=readout,
        passive=passive,
        channels=channels,  # type: ignore[arg-type]
    )
    outputs = ["readings", *(["passive"] if has_passive else []), "latent"]
    data = {
        "name": name,
        "task": "thermal",
        "description": f"calibrated from {len(rows)} labelled touches ({', '.join(n for n, _ in classes)})",
        "outputs": outputs,
        "noise": True,
        "thermal": _plain(config),
    }
    try:
        return parse_scene(data, f"<{name}>")
    except ConfigError as exc:
        raise DataError(
            f"the calibrated scene does not validate ({exc}); calibrate with more or longer touches"
        ) from None


def _sensor_config(v: dict[str, float], rows: list[dict[str, float]], ambient_values: list[float]) -> SensorConfig:
    """The heated channel's sensor from the fitted values ``v`` and the touches' rows: the fit
    widened, the set point and ambient spanning the touches, the heater's power change per touch."""
    lead = v["contact.lead_s"]
    off = v.get("heater.off_after_onset_s")
    heated_start = [r["heated_onset_c"] for r in rows]
    ambient = _span(ambient_values, 0.5)
    g = v["heated.loss_w_m2k"]
    set_point = _span(heated_start, 0.15)
    steps = [0.0]
    step_times = [lead + off] if off is not None else []
    if off is not None and "heater_step_at_off_w_m2" in rows[0]:
        # per-touch steps at the contact and at t_off: the scene's heater makes one step, of their
        # sum, somewhere between the two times (its timing is widened over that span)
        steps = [r["heater_step_at_contact_w_m2"] + r["heater_step_at_off_w_m2"] for r in rows]
        step_times = [lead, lead + off]
    elif off is not None:  # the fitted change of heater power at t_off, per touch: -(G (R0 + r lead - T_amb) + C r)
        lags = v["heated.lag_s"] + v["heated.lag2_s"]
        steps = [
            -(g * (r["heated_onset_c"] + r["heated_drift_k_s"] * lags - v["heater.ambient_c"]))
            - v["heated.heat_capacity_j_m2k"] * r["heated_drift_k_s"]
            for r in rows
        ]
    return SensorConfig(
        heat_capacity_j_m2k=_around(v["heated.heat_capacity_j_m2k"], 0.05),
        loss_w_m2k=_around(g, 0.15, 1e-3),
        heater_w_m2=_around(max(g * (float(np.mean(heated_start)) - float(np.mean(ambient_values))), 1e-3), 0.2, 1e-3),
        pixel_spread=0.0,
        ambient_c=ambient,
        lag_s=_around(v["heated.lag_s"], 0.15),
        lag2_s=_around(v["heated.lag2_s"], 0.15),
        heater="step" if off is not None else "constant",
        set_point_c=set_point,
        heater_off_s=_span(step_times, 0.3) if off is not None else (0.0, 0.0),
        heater_step_w_m2=(min(steps) - 0.2 * abs(min(steps)), max(steps) + 0.2 * abs(max(steps))),
        drift_k_s=_span([r["heated_drift_k_s"] for r in rows], 0.02),
    )


def _passive_config(v: dict[str, float], rows: list[dict[str, float]], factors: list[float]) -> PassiveConfig:
    """The passive channel from the fitted values ``v``, the touches' rows and their contact
    factors (its contact spans the heated one's spread)."""
    hp = v["passive.conductance_w_m2k"]
    # the passive channel's drift before contact: a pull towards the object (it is already
    # cooling over a cold one) plus what is left, from the touches' fitted drifts
    pull = np.array([r["object_c"] - r["passive_onset_c"] for r in rows])
    drift = np.array([r["passive_drift_k_s"] for r in rows])
    rate = max(float((pull * drift).sum() / max((pull**2).sum(), 1e-12)), 0.0)
    rest = drift - rate * pull
    return PassiveConfig(
        enabled=True,
        heat_capacity_j_m2k=_around(v["passive.heat_capacity_j_m2k"], 0.05),
        loss_w_m2k=_around(v["passive.loss_w_m2k"], 0.15),
        conductance_w_m2k=(hp * min(factors) / 1.2, hp * max(factors) * 1.2),
        lag_s=_around(v["passive.lag_s"], 0.15),
        lag2_s=_around(v["passive.lag2_s"], 0.15),
        offset_k=(-0.5, 0.5),
        drift_k_s=_span([float(rest.min()), float(rest.max())], 0.02),
        approach_per_s=(0.5 * rate, 1.5 * rate),
    )


def _plain(config: ThermalConfig) -> dict[str, Any]:
    from synth.config import to_dict

    return dict(to_dict(config))


def write_scene(scene: Scene, out: str | Path, report: dict[str, Any] | None = None) -> Path:
    """Write ``scene`` as TOML (atomically) after checking it loads back; the calibration's headline
    goes in a comment."""
    text = dumps_toml(scene.to_dict())
    try:
        parse_scene(tomllib.loads(text), str(out))
    except ConfigError as exc:  # nothing is written: a scene that does not load back is useless
        raise DataError(f"{out}: the calibrated scene does not load back ({exc}); nothing written") from None
    header = "# Written by tactile-learn calibrate: the sensor's own parameters.\n"
    if report is not None:
        res = report.get("residual", {})
        rms_mk, sigma = res.get("rms_k", math.nan) * 1e3, res.get("rms_sigma", math.nan)
        header += f"# residual {rms_mk:.1f} mK RMS = {sigma:.1f} noise sigma\n"
    atomic_write_text(out, header + text)
    return Path(out)
