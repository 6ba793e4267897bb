"""From a user's labelled recordings to a scene of their sensor (calibration) and a classifier for it.

:func:`calibrate_recordings`: the labels become the scene's classes (materials, families or the
user's own classes), every labelled touch's onset is found (force, else the curve), the noise is
measured, and :func:`~tactile_learn.thermal_calibration.calibrate_channels` fits the sensor; the
fitted values, widened a little (a sensor drifts from day to day, and a model that explains the
curves to a few hundredths of a kelvin should not train a network on one exact shape), become a
scene whose objects' temperatures are unknown over a wide range (cooled and warmed objects). The
scene is validated (it must load back) before it is written, atomically.

:func:`adapt` (numpy, scipy and torch): calibrate, generate a training and a validation set from
the calibrated scene, train a small network, evaluate it on the labelled real touches themselves
(the validation a user can trust: the synthetic set only shows the network learnt the simulator),
export ONNX with a card holding the calibration report, the classes, the channels and the metrics,
and warn when the real-touch accuracy is near chance.
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
from tactile_learn.thermal_calibration import (
    FIT_HZ,
    CalibrationResult,
    calibrate_channels,
    noise_levels,
    prepare_touches,
)
from tactile_learn.thermal_recordings import Touch, press_onset, read_recordings, resample

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = ["CHANNEL_CHOICES", "adapt", "adapt_scene", "calibrate_recordings", "scene_from_fit", "write_scene"]

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
    from tactile_learn.estimators.classical.curve_match import detect_onset

    fs = touch.sampling_hz
    values, _ = resample(touch, fs)
    found = detect_onset(values[None, :], fs)
    if not found.detected[0]:
        raise DataError(f"{touch.file}: no contact found (no force column, and the curve shows no departure)")
    return float(touch.time_s[0]) + (float(found.index[0]) + 0.5) / fs, "curve"


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
) -> tuple[Scene, dict[str, Any]]:
    """Fit the user's sensor from the labelled touches in ``source``; returns the scene and the
    calibration report (see the module docstring). The passive channel is fitted whenever every
    touch has one (it pins the object's temperature), whatever ``channels`` the scene's classifier
    will read."""
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
    result = calibrate_channels(fit_touches, materials, noise, starts=starts, seed=seed)
    scene = scene_from_fit(result, classes, channels, noise, name=name)
    report = dict(result.report)
    report["classes"] = {n: list(m) for n, m in classes}
    report["touches"] = [
        {"file": t.file, "label": t.material, "onset_from": how, **row}
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
    lead = v["contact.lead_s"]
    off = v.get("heater.off_after_onset_s")
    heated_start = [r["heated_onset_c"] for r in rows]
    ambient_values = [r["passive_onset_c"] for r in rows] if has_passive else [v.get("heater.ambient_c", 22.0)]
    ambient = _span(ambient_values, 0.5)
    g = v["heated.loss_w_m2k"]
    set_point = _span(heated_start, 0.15)
    steps = [0.0]
    if off is not None:  # the fitted change of heater power at t_off, per touch: -(G (R0 + r lead - T_amb) + C r)
        lags = v["heated.lag_s"] + v["heated.lag2_s"]
        steps = [
            -(g * (r["heated_onset_c"] + r["heated_drift_k_s"] * lags - v["heater.ambient_c"]))
            - v["heated.heat_capacity_j_m2k"] * r["heated_drift_k_s"]
            for r in rows
        ]
    sensor = SensorConfig(
        heat_capacity_j_m2k=_around(v["heated.heat_capacity_j_m2k"], 0.05),
        loss_w_m2k=_around(g, 0.15, 1e-3),
        heater_w_m2=_around(max(g * (float(np.mean(heated_start)) - float(np.mean(ambient_values))), 1e-3), 0.2, 1e-3),
        pixel_spread=0.0,
        ambient_c=ambient,
        lag_s=_around(v["heated.lag_s"], 0.15),
        lag2_s=_around(v["heated.lag2_s"], 0.15),
        heater="step" if off is not None else "constant",
        set_point_c=set_point,
        heater_off_s=_span([lead + off], 0.3) if off is not None else (0.0, 0.0),
        heater_step_w_m2=(min(steps) - 0.2 * abs(min(steps)), max(steps) + 0.2 * abs(max(steps))),
        drift_k_s=_span([r["heated_drift_k_s"] for r in rows], 0.02),
    )
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
    passive = PassiveConfig()
    if has_passive:
        hp = v["passive.conductance_w_m2k"]
        # the passive channel's drift before contact: a pull towards the object (it is already
        # cooling over a cold one) plus what is left, from the touches' fitted drifts
        pull = np.array([r["object_c"] - r["passive_onset_c"] for r in rows])
        drift = np.array([r["passive_drift_k_s"] for r in rows])
        rate = max(float((pull * drift).sum() / max((pull**2).sum(), 1e-12)), 0.0)
        rest = drift - rate * pull
        passive = PassiveConfig(
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


#: accuracy on the labelled touches below chance + this is reported as "near chance"
NEAR_CHANCE = 0.15


def adapt(
    data: str | Path,
    out: str | Path,
    *,
    channels: str = "all",
    class_map: dict[str, tuple[str, ...]] | None = None,
    starts: int = 6,
    seed: int = 0,
    **options: Any,
) -> dict[str, Any]:
    """Calibrate, generate, train, validate on the labelled touches, export (module docstring).

    ``out`` receives ``sensor.toml`` (the calibrated scene), ``calibration.json``, ``train/`` and
    ``val/`` (synthetic datasets), ``run/`` (the training run) and ``model.onnx`` + ``model.json``
    (its card). ``options`` go to :func:`adapt_scene`. Returns the card.
    """
    import time

    if channels not in CHANNEL_CHOICES:
        raise ConfigError(f"--channels: {channels!r} is not one of {', '.join(CHANNEL_CHOICES)}")
    folder = Path(out)
    if folder.exists() and any(folder.iterdir()):
        raise DataError(f"{folder} is not empty: adapt writes a fresh folder (choose another --out)")
    started = time.perf_counter()
    scene, report = calibrate_recordings(
        data, CHANNEL_CHOICES[channels], class_map, starts=starts, seed=seed, name=f"adapted_{channels}"
    )
    report["seconds"] = time.perf_counter() - started
    return adapt_scene(scene, report, data, folder, channels=channels, seed=seed, **options)


def adapt_scene(
    scene: Scene,
    report: dict[str, Any],
    data: str | Path,
    out: str | Path,
    *,
    channels: str = "all",
    n_train: int = 16000,
    n_val: int = 1000,
    epochs: int = 12,
    size: str = "tiny",
    seed: int = 0,
    threads: int = 1,
    workers: int = 1,
    progress: bool | None = None,
) -> dict[str, Any]:
    """Everything after the calibration (``scene``, ``report``): the classifier reads ``channels``."""
    import dataclasses
    import time

    from synth.config import replace
    from synth.dataset import generate
    from synth.io import atomic_write_json
    from tactile_learn.export import export
    from tactile_learn.runtime import OnnxEstimator, card_path
    from tactile_learn.tasks.thermal import ThermalTask
    from tactile_learn.train import TrainConfig, train

    started = time.perf_counter()
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    config = replace(scene.sensor, "channels", list(CHANNEL_CHOICES[channels]))
    scene = dataclasses.replace(scene, sensor=config, name=f"adapted_{channels}")
    write_scene(scene, folder / "sensor.toml", report)
    atomic_write_json(folder / "calibration.json", report)
    timings: dict[str, float] = {"calibrate_s": float(report.get("seconds", report["solver"]["seconds"]))}
    mark = time.perf_counter()
    generate(scene, n_train, seed * 2 + 1, folder / "train", workers=workers, shard_size=4096)
    generate(scene, n_val, seed * 2 + 2, folder / "val", workers=workers, shard_size=4096)
    timings["generate_s"] = time.perf_counter() - mark
    mark = time.perf_counter()
    # the labelled real touches are the validation set: the epoch kept is the one that classifies
    # the user's own touches best (a synthetic validation set only shows the simulator was learnt)
    train_config = TrainConfig(
        task="thermal",
        data=str(folder / "train"),
        val=str(data),
        out=str(folder / "run"),
        size=size,
        epochs=epochs,
        seed=seed,
        threads=threads,
        patience=epochs,
    )
    train(train_config, progress=progress)
    timings["train_s"] = time.perf_counter() - mark
    mark = time.perf_counter()
    card = export(folder / "run", folder / "model.onnx", name=f"adapted_{channels}", test=folder / "val")
    task = ThermalTask()
    real = task.evaluate(OnnxEstimator(folder / "model.onnx"), task.load_eval_data(data, scene))
    timings["export_s"] = time.perf_counter() - mark
    k = len(scene.sensor.class_names)
    chance = 1.0 / k
    warnings = []
    if not real["accuracy"] >= chance + NEAR_CHANCE:
        warnings.append(
            f"accuracy on the labelled touches is {real['accuracy']:.2f}, near chance ({chance:.2f}): the calibrated "
            "simulator does not explain these touches well enough (see calibration.json: residual, parameters at "
            "a bound); label more touches, check the labels and the onsets, or classify with a few-shot method "
            "trained on the labelled touches alone (tactile-learn eval --task thermal --method press_aligned "
            f"--train {Path(data)} --scene {folder / 'sensor.toml'} --data YOUR_TOUCHES)"
        )
    if report["residual"]["rms_sigma"] > 3.0:
        warnings.append(
            f"the calibration leaves {report['residual']['rms_k'] * 1e3:.1f} mK RMS "
            f"({report['residual']['rms_sigma']:.1f} noise sigma): the model does not explain every detail"
        )
    timings["total_s"] = timings["calibrate_s"] + time.perf_counter() - started
    card["classes"] = list(scene.sensor.class_names)
    card["channels"] = list(scene.sensor.channels)
    card["calibration"] = report
    card["metrics"]["labelled_touches"] = {"data": Path(data).name, "values": real}
    card["adapt"] = {"timings_s": timings, "n_train": n_train, "n_val": n_val, "epochs": epochs, "size": size}
    card["warnings"] = warnings
    atomic_write_json(card_path(folder / "model.onnx"), card)
    return card
