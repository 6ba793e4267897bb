"""The thermal task's evaluation data: touches from arrays (a generated dataset, an ``.npz``) or a
recording directory, each with its whole record, onset and label, and their views by contact
duration (:func:`view`). The formats: :mod:`tactile_learn.tasks.thermal`."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from synth.errors import DataError
from synth.scene import Scene
from synth.sensors.thermal import ThermalConfig
from tactile_learn.tasks.base import EvalData
from tactile_learn.tasks.thermal_classes import (
    NONE,
    channel_keys,
    labels_from_materials,
    recording_labels,
    thermal_config,
)
from tactile_learn.thermal_signal import onset_seconds, press_onset, press_profile, windows

if TYPE_CHECKING:
    from tactile_learn.thermal_recordings import Touch

__all__ = ["detect_onsets", "eval_data_from_arrays", "eval_data_from_recordings", "view"]


def view(data: EvalData, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The view of ``data`` at contact duration ``duration_s``: windows (N, W) (one channel) or
    (N, C, W) (several), and a mask of the rows whose record (and contact, when its release is
    known) reaches ``onset + duration_s``."""
    cfg = thermal_config(data.scene)
    fs = cfg.readout.sampling_hz
    length, onset = data.extra["length"], data.extra["onset_s"]
    end_s = np.floor((onset.astype(np.float64) + duration_s) * fs + 1e-9) + 1
    end = np.clip(end_s, 0, length + 1).astype(np.int64)  # clipped first: a far-off onset does not overflow
    valid = end <= length
    if "release_s" in data.extra:  # a simulated touch: the view must end before the release
        valid &= onset + duration_s <= data.extra["release_s"] + 1e-9
    ends = np.minimum(end, length)
    parts = [windows(data.extra[key], length, ends, cfg.window_samples) for key in channel_keys(cfg)]
    return (parts[0] if len(parts) == 1 else np.stack(parts, axis=1)), valid


def eval_data_from_arrays(arrays: dict[str, np.ndarray], scene: Scene, source: str) -> EvalData:
    """Evaluation data from simulated or user arrays (see :mod:`tactile_learn.tasks.thermal`): every
    pixel's record, its onset (given, else detected) and label; inputs are the views at 2 s."""
    cfg = thermal_config(scene)
    if "readings" not in arrays:
        raise DataError(f"{source}: needs an array 'readings' (B, R) or (B, P, R) of temperatures (degC)")
    readings = np.asarray(arrays["readings"])
    if not np.issubdtype(readings.dtype, np.number) or np.iscomplexobj(readings):
        raise DataError(f"{source}: readings must be real numbers (degC), got dtype {readings.dtype}")
    if readings.ndim == 2:
        readings = readings[:, None, :]
    if readings.ndim != 3 or readings.shape[2] < 2:
        raise DataError(f"{source}: readings have shape {readings.shape}, expected (B, R) or (B, P, R)")
    b, p, r = readings.shape
    k = len(cfg.material_list)

    def per_touch(name: str, values: Any) -> np.ndarray:
        """``values`` as (B, P) (one per pixel) or (B, 1) (one per touch)."""
        arr = np.asarray(values)
        if arr.size == b * p:
            return arr.reshape(b, p)
        if arr.size == b:
            return arr.reshape(b, 1)
        raise DataError(f"{source}: {name} have shape {arr.shape}, readings {readings.shape} need {(b, p)}")

    mat, class_level = _material_labels(arrays, cfg, per_touch, source)
    if mat.shape != (b, p):
        raise DataError(f"{source}: labels have shape {mat.shape}, readings {readings.shape} need {(b, p)}")
    if not class_level and mat.size and (mat.max() >= k or mat.min() < -1):
        raise DataError(f"{source}: material indices must lie in [-1, {k - 1}] for scene {scene.name!r}")
    records = readings.reshape(b * p, r).astype(np.float32)
    onset_key = next((key for key in ("latent_onset_s", "onset_s") if key in arrays), None)
    if onset_key is not None:
        given = per_touch(onset_key, arrays[onset_key])
        if not np.issubdtype(given.dtype, np.number) or not np.isfinite(given).all():
            raise DataError(f"{source}: {onset_key} must be finite numbers (s from the record's start)")
        onset = np.broadcast_to(given.astype(np.float64), (b, p)).ravel()
    else:
        onset = detect_onsets(records, cfg)
    extra: dict[str, np.ndarray] = {
        "record": records,
        "length": np.full(b * p, r, dtype=np.int64),
        "onset_s": onset.astype(np.float64),
        "touch": np.repeat(np.arange(b), p),
        "pixel": np.tile(np.arange(p), b),
    }
    for channel in cfg.channels[1:]:
        if channel not in arrays:
            raise DataError(f"{source}: scene {scene.name!r} reads the {channel} channel: needs an array {channel!r}")
        other = np.asarray(arrays[channel])
        if other.size != b * p * r:
            raise DataError(f"{source}: {channel} has shape {other.shape}, readings {readings.shape}")
        extra[f"record_{channel}"] = other.reshape(b * p, r).astype(np.float32)
    for key, value in arrays.items():
        if key.startswith("latent_") and np.asarray(value).shape[:2] == (b, p):
            extra[key] = np.asarray(value).reshape(b * p, *np.asarray(value).shape[2:])
    if "latent_release_s" in extra:
        extra["release_s"] = extra["latent_release_s"].astype(np.float64)
    flat = mat.ravel()
    labels = np.where(flat < 0, len(cfg.class_names), flat) if class_level else labels_from_materials(flat, k, cfg)
    data = EvalData(
        inputs=np.zeros((b * p, 0), np.float32), truth={"label": labels}, scene=scene, extra=extra, source=source
    )
    data.inputs = view(data, 2.0)[0]
    return data


def _material_labels(
    arrays: dict[str, np.ndarray], cfg: ThermalConfig, per_touch: Callable[[str, Any], np.ndarray], source: str
) -> tuple[np.ndarray, bool]:
    """Every pixel's label (B, P) from ``latent_material`` (material indices, -1 = none) or
    ``material`` (names of classes or materials), and whether they are class indices already."""
    if "latent_material" in arrays:
        mat = per_touch("labels", arrays["latent_material"])
        integral = mat.dtype.kind in "iu" or (
            mat.dtype.kind == "f" and bool(np.isfinite(mat).all()) and bool((mat == np.round(mat)).all())
        )
        if not integral:
            raise DataError(
                f"{source}: latent_material must hold integer material indices (-1 = none), got dtype {mat.dtype}"
            )
        mat = mat.astype(np.int64)
        class_level = False
    elif "material" in arrays:
        names = list(cfg.class_names)
        mat_names = [m.name for m in cfg.material_list]
        raw = per_touch("labels", arrays["material"])
        unknown = sorted({str(v) for v in raw.ravel() if str(v) not in (*names, *mat_names, NONE, "")})
        if unknown:
            raise DataError(f"{source}: label(s) {', '.join(unknown)} not in the scene's classes ({', '.join(names)})")

        def to_class(v: str) -> int:
            if v in names:
                return names.index(v)
            if v in mat_names:
                return int(cfg.class_of_material[mat_names.index(v)])
            return -1

        mat = np.array([to_class(str(v)) for v in raw.ravel()], dtype=np.int64).reshape(raw.shape)
        class_level = True
    else:
        raise DataError(f"{source}: needs labels 'latent_material' (material index, -1 = none) or 'material' (names)")
    return mat, class_level


def detect_onsets(records: np.ndarray, cfg: ThermalConfig) -> np.ndarray:
    """Every record's onset (s) from its curve's departure (no onset given)."""
    return onset_seconds(records, cfg.readout.sampling_hz, cfg.readout.adc_step_k)[0]


def eval_data_from_recordings(path: Path, scene: Scene) -> EvalData:
    """Evaluation data from a recording directory (:mod:`tactile_learn.thermal_recordings`): every
    touch's channels on the scene's grid, its press (force) profile, its onset (given, else the
    force's, else the curve's) and label; inputs are the views at 2 s."""
    from tactile_learn.thermal_recordings import read_recordings, resample_channel

    cfg = thermal_config(scene)
    fs = cfg.readout.sampling_hz
    touches = read_recordings(path, **recording_labels(cfg))
    channels = [("record", "temperature_c")] + [(f"record_{c}", f"{c}_c") for c in cfg.channels[1:]]
    for t in touches:
        for _, column in channels[1:]:
            if getattr(t, column) is None:
                raise DataError(f"{path / t.file}: scene {scene.name!r} reads {column}: the file has no such column")
    series = {key: [resample_channel(t, column, fs) for t in touches] for key, column in channels}
    lengths = np.array([len(v) for v in series["record"]], dtype=np.int64)
    r = int(lengths.max())
    extra: dict[str, np.ndarray] = {}
    for key, values in series.items():
        records = np.empty((len(touches), r), dtype=np.float32)
        for i, v in enumerate(values):
            records[i, : len(v)] = v
            records[i, len(v) :] = v[-1]
        extra[key] = records
    detected = detect_onsets(extra["record"], cfg)
    # the press (force / its plateau) on the same grid, for methods that time the contact by it
    press, has_press = _press_records(touches, lengths, fs, r)
    extra.update(press=press, has_press=has_press)
    onset, source = _onsets(touches, detected)
    names = list(cfg.class_names)
    labels = np.array([names.index(t.material) if t.material else -2 for t in touches])
    extra.update(
        length=lengths,
        onset_s=onset,
        onset_from=source,
        labelled=labels >= 0,
        touch=np.arange(len(touches)),
        pixel=np.zeros(len(touches), dtype=np.int64),
        file=np.array([t.file for t in touches], dtype=object),
    )
    for column in sorted({k for t in touches for k in t.info}):
        extra[f"info:{column}"] = np.array([t.info.get(column, "") for t in touches], dtype=object)
    if any(t.info.get("release_s") for t in touches):  # views must end before a release
        extra["release_s"] = np.array(
            [float(t.info["release_s"]) - float(t.time_s[0]) if t.info.get("release_s") else np.inf for t in touches]
        )
    data = EvalData(
        inputs=np.zeros((len(touches), 0), np.float32),
        truth={"label": np.where(labels >= 0, labels, len(names))},
        scene=scene,
        extra=extra,
        source=str(path),
    )
    data.inputs = view(data, 2.0)[0]
    # a record shorter than onset + 2 s is classified on what it has (its end)
    return data


def _press_records(touches: Sequence[Touch], lengths: np.ndarray, fs: float, r: int) -> tuple[np.ndarray, np.ndarray]:
    """Every touch's press profile (force over its plateau) on the records' grid (N, R), padded
    with its last value, and which touches have one (a force column)."""
    press = np.zeros((len(touches), r), dtype=np.float32)
    has_press = np.zeros(len(touches), dtype=bool)
    for i, t in enumerate(touches):
        profile = press_profile(t.time_s, t.force) if t.force is not None else None
        if profile is not None:
            values = np.interp(t.time_s[0] + np.arange(lengths[i]) / fs, t.time_s, profile)
            press[i, : len(values)] = values
            press[i, len(values) :] = values[-1]
            has_press[i] = True
    return press, has_press


def _onsets(touches: Sequence[Touch], detected: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every touch's onset (s from its record's start) and where it comes from: touches.csv
    (``given``), the force's half-plateau crossing (``force``), else the curve (``curve``)."""
    onset = np.empty(len(touches))
    source = np.empty(len(touches), dtype=object)
    for i, t in enumerate(touches):
        t0 = float(t.time_s[0])
        pressed = press_onset(t.time_s, t.force) if t.force is not None else None
        if t.onset_s is not None:
            onset[i], source[i] = t.onset_s - t0, "given"
        elif pressed is not None:
            onset[i], source[i] = pressed - t0, "force"
        else:
            onset[i], source[i] = detected[i], "curve"
    return onset, source
