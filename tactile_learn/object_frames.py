"""An object's frames as tomography reads them: row and column loads per frame, and which frames can be fitted
(numpy only: the learned-object checks run where torch is not installed; the fit is
:mod:`tactile_learn.object_tomography`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from synth.errors import ConfigError, InputError
from synth.sensors.strips.config import StripsConfig
from synth.sensors.strips.physics import StripSensor

__all__ = ["frame_loads", "orthogonal_only", "readable_object_frames"]


def orthogonal_only(config: StripsConfig) -> None:
    if config.geometry.layout != "orthogonal":
        raise ConfigError(
            f"object tomography reads one row and one column projection per frame: layout "
            f"{config.geometry.layout!r} is not the orthogonal pair"
        )


def frame_loads(readings: np.ndarray, sensor: StripSensor) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row and column loads (B, N), (B, M), each frame divided by its load (the mean of its row and column
    totals), and that load (B,)."""
    loads = sensor.invert_readings(np.asarray(readings, dtype=np.float64))
    rows, cols = loads[:, : sensor.n_rows], loads[:, sensor.n_rows : sensor.n_rows + sensor.n_cols]
    total = 0.5 * (rows.sum(1) + cols.sum(1))
    scale = np.maximum(total, 1e-12)[:, None]
    return rows / scale, cols / scale, total


def readable_object_frames(
    readings: Any, config: StripsConfig, min_frames: int = 1
) -> tuple[np.ndarray, dict[str, int]]:
    """The frames of ``readings`` (B, N+M) a template can be fitted to, and how many were left out why.

    Refused by name: a wrong shape, NaN or inf, readings outside the ADC's range. Left out and
    counted: idle frames (a load within 5 standard deviations of the readout's noise: no object on the
    array) and saturated ones (a channel at the ADC's top: its load is unknown). Fewer than
    ``min_frames`` left is an error: a shape cannot be told from a handful of projections."""
    orthogonal_only(config)
    sensor = StripSensor(config)
    x = np.asarray(readings)
    channels = sensor.n_rows + sensor.n_cols
    if x.ndim != 2 or x.shape[1] != channels:
        raise InputError(f"readings: expected shape (frames, {channels}) for this array, got {x.shape}")
    if not np.issubdtype(x.dtype, np.number) or not np.isfinite(x).all():
        raise InputError("readings: NaN, inf or non-numeric values; every frame must be a finite reading")
    top = config.readout.full_scale_v
    if (x < 0).any() or (x > top + 1e-6).any():
        raise InputError(f"readings: values outside the ADC's range [0, {top:g}] V")
    _, _, total = frame_loads(x, sensor)
    floor = 5.0 * 0.5 * float(np.sqrt((sensor.load_noise() ** 2).sum()))
    idle = total <= floor
    saturated = (x >= top - config.readout.lsb_v).any(axis=1)
    keep = ~idle & ~saturated
    counts = {
        "frames": len(x),
        "idle": int(idle.sum()),
        "saturated": int((saturated & ~idle).sum()),
        "used": int(keep.sum()),
    }
    if counts["used"] < min_frames:
        raise InputError(
            f"readings: {counts['used']} frames with an object on the array ({counts['idle']} idle, "
            f"{counts['saturated']} saturated of {counts['frames']}); at least {min_frames} are needed"
        )
    return x[keep].astype(np.float32), counts
