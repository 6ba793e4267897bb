"""The thermal signal: onset detection, windows, and the press profile of a force record.

Used by the thermal task (views, onsets of records without labels), the thermal estimators (onset
alignment), calibration and few-shot learning: one implementation of each step, below all of them.

**Onset detection** (:func:`detect_onset`, the seed's curve matching's step 1): baseline ``b``
(median) from the window's first 0.1 s and noise ``sigma`` from the successive differences over its
first 0.2 s (a flat run of padding at the start is skipped, unless the readings leave it for good
where it ends: then it is a noise-free baseline); the departure ``dev = dir (b - x)`` (``dir`` =
sign of the final departure, so a warm object works too) must exceed ``max(5 sigma, 2 ADC steps)``
on two consecutive samples; the onset sample ``k0`` is the last sample before that crossing still
within ``1.5 sigma`` of the baseline. The baseline is then re-estimated from the samples before
``k0``.

:func:`onset_seconds` turns a detection into a time (s from the record's start: the middle of the
sample step the contact began in). :func:`windows` cuts fixed-width windows out of records (the
task's duration views, training windows). :func:`press_profile` / :func:`press_onset` read a force
record (a robot's or a load cell's): the press normalised to its plateau, and the time it crosses
half of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter

__all__ = [
    "FORCE_FILTER_S",
    "LOOKBACK",
    "Onset",
    "detect_onset",
    "drop_segments",
    "onset_seconds",
    "press_onset",
    "press_profile",
    "windows",
]

#: samples before the detected onset that the alignment may reach back to
LOOKBACK = 3
#: mean of the squares of ~10 standard normals without the largest (noise estimate's correction)
_TRIM_FACTOR = 0.69
#: median filter (s) of a force record before its plateau is read
FORCE_FILTER_S = 0.125


@dataclass(frozen=True)
class Onset:
    """Per-curve onset detection (arrays of length B)."""

    index: np.ndarray  # k0: last baseline sample (int); W - 1 when nothing was detected
    detected: np.ndarray  # bool
    baseline: np.ndarray  # degC
    sigma: np.ndarray  # K, noise s.d. estimate (floored)
    direction: np.ndarray  # +1 the pixel cools on contact (object colder), -1 it warms


def detect_onset(x: np.ndarray, fs: float, adc_step: float = 0.0, base_s: float = 0.1) -> Onset:
    """Onset alignment of curves ``x`` (B, W) (see the module docstring, step 1).

    A flat run (3 or more equal samples) at the window's start is taken for padding and skipped
    when estimating the baseline and the noise, unless the readings leave its value for good right
    where it ends (they depart strictly monotonically, cross the threshold within ``LOOKBACK``
    samples and never come back): then it is a noise-free baseline (a clean or sub-LSB-noise
    sensor), skipping it would estimate the noise from the contact itself, and the curve is detected
    without the skip (baseline: the run's value; noise: the floor).
    """
    x = np.asarray(x, dtype=np.float64)
    w = x.shape[1]
    # a window that starts before its record is padded with the record's first sample: skip that
    # flat run (3 or more equal samples) when estimating the noise
    flat = np.cumprod(x == x[:, :1], axis=1).sum(axis=1)
    start = np.where(flat >= 3, flat - 1, 0)
    n0 = int(min(max(3, round(base_s * fs)), max(1, w // 2)))
    onset, _ = _detect_from(x, start, np.full(len(x), w), n0, adc_step)
    runs = np.flatnonzero(start > 0)
    if len(runs):
        # the other reading: the run is the baseline (its value) and the noise (none: the floor)
        xr = x[runs]
        plain, k1 = _detect_from(xr, np.zeros(len(runs), dtype=np.int64), flat[runs], n0, adc_step)
        end = flat[runs] - 1  # the run's last sample
        idx = np.arange(w)[None, :]
        dev = plain.direction[:, None] * (xr[:, :1] - xr)
        back = (idx >= k1[:, None]) & (dev <= 1.5 * plain.sigma[:, None])
        # the first samples after the run depart strictly monotonically (noise around a padded value
        # does not: it settles at once)
        rise = np.diff(dev, axis=1, prepend=0.0)
        stall = (idx > end[:, None]) & (idx <= end[:, None] + 1 + LOOKBACK) & (rise <= 0)
        baseline_run = plain.detected & (k1 <= end + LOOKBACK) & ~back.any(axis=1) & ~stall.any(axis=1)
        rows = runs[baseline_run]
        for name in ("index", "detected", "baseline", "sigma", "direction"):
            getattr(onset, name)[rows] = getattr(plain, name)[baseline_run]
    return onset


def _span_median(x: np.ndarray, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
    """Median of every row of ``x`` (B, W) over its samples ``start <= k < stop`` (NaN where the span
    is empty): ``nanmedian`` of the span, computed on the span alone (numpy's ``nanmedian`` of a few
    rows goes through masked arrays: most of a single curve's detection time)."""
    w = x.shape[1]
    width = max(int((stop - start).max(initial=0)), 1)
    cols = start[:, None] + np.arange(width)[None, :]
    inside = (cols < stop[:, None]) & (cols < w)
    # samples outside the span sort after every real one
    span = np.sort(np.where(inside, np.take_along_axis(x, np.minimum(cols, w - 1), axis=1), np.inf), axis=1)
    count = inside.sum(axis=1)
    lo = np.take_along_axis(span, np.maximum(count - 1, 0)[:, None] // 2, axis=1)[:, 0]
    hi = np.take_along_axis(span, np.minimum(count // 2, width - 1)[:, None], axis=1)[:, 0]
    # numpy's median is the mean of the middle sample(s): + 0.0 gives its +0 for a -0 reading too
    middle = np.where(count % 2 == 1, lo, (lo + hi) / 2.0) + 0.0
    return np.where(count > 0, middle, np.nan)


def _detect_from(
    x: np.ndarray, start: np.ndarray, stop: np.ndarray, n0: int, adc_step: float
) -> tuple[Onset, np.ndarray]:
    """:func:`detect_onset` with the baseline and noise spans starting at sample ``start`` (B,) and
    ending before ``stop`` (B,); also returns the first threshold crossing ``k1`` (B,) (``W - 1``
    when nothing was detected)."""
    w = x.shape[1]
    idx = np.arange(w)[None, :]
    inside = idx < stop[:, None]
    b0 = _span_median(x, start, np.minimum(start + n0, stop))
    b0 = np.where(np.isfinite(b0), b0, x[:, -1])
    floor = max(adc_step / math.sqrt(12.0), 1e-3)  # quantisation noise; never a zero sigma
    span = (idx >= start[:, None]) & (idx < start[:, None] + 2 * n0) & inside
    # noise from successive differences (robust to a slow drift, exact for quantised readings,
    # unlike a median): the mean square without the largest one (a stray onset), d ~ N(0, 2 s^2)
    pair = span[:, 1:] & span[:, :-1]
    d2 = np.where(pair, np.diff(x, axis=1) ** 2, 0.0)
    count = pair.sum(axis=1)
    trimmed = (d2.sum(axis=1) - d2.max(axis=1, initial=0.0)) / np.maximum(count - 1, 1)  # count - 1 >= 1 where used
    sigma0 = np.where(count >= 3, np.sqrt(trimmed / (2.0 * _TRIM_FACTOR)), 0.0)
    sigma0 = np.maximum(sigma0, floor)
    tail = x[:, -min(3, w) :].mean(axis=1)
    direction = np.where(tail <= b0, 1.0, -1.0)
    dev = direction[:, None] * (b0[:, None] - x)
    thr = np.maximum(5.0 * sigma0, 2.0 * adc_step)[:, None]
    above = dev > thr
    both = above.copy()
    both[:, :-1] &= above[:, 1:]
    detected = both.any(axis=1)
    k1 = np.where(detected, np.argmax(both, axis=1), w - 1)
    quiet = (dev <= 1.5 * sigma0[:, None]) & (idx < k1[:, None])
    k0 = np.where(quiet.any(axis=1), np.where(quiet, idx, -1).max(axis=1), np.maximum(k1 - 1, 0))
    k0 = np.where(detected, k0, w - 1)
    # baseline again from the samples before the onset (at least 3, else the first n0)
    upto = np.maximum(k0 - 1, 0)
    use = idx < upto[:, None]
    count = use.sum(axis=1)
    mean = np.where(use, x, 0.0).sum(axis=1) / np.maximum(count, 1)  # count >= 1 where used
    baseline = np.where(count >= 3, mean, b0)
    return Onset(k0.astype(np.int64), detected, baseline, sigma0, direction), k1


def drop_segments(x: np.ndarray, onset: Onset, lookback: int = LOOKBACK) -> tuple[np.ndarray, np.ndarray]:
    """Observed drops ``y`` (B, J + W) aligned at the onset (``y[:, J + j]`` is sample ``k0 + j``,
    zero past the window's end) and the number of valid entries per curve."""
    x = np.asarray(x, dtype=np.float64)
    w = x.shape[1]
    j = np.arange(-lookback, w)[None, :]
    src = onset.index[:, None] + j
    valid = (src >= 0) & (src < w)
    vals = np.take_along_axis(x, np.clip(src, 0, w - 1), axis=1)
    y = np.where(valid, onset.direction[:, None] * (onset.baseline[:, None] - vals), 0.0)
    n_valid = lookback + w - onset.index  # entries from j = -J up to the window's last sample
    return y, n_valid


def onset_seconds(records: np.ndarray, fs: float, adc_step: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Onsets (s from each record's start) of records (N, R) and whether one was detected (0 s where
    not): the contact starts between the last baseline sample ``k0`` and the next one."""
    onset = detect_onset(records, fs, adc_step)
    return np.where(onset.detected, (onset.index + 0.5) / fs, 0.0), onset.detected


def windows(records: np.ndarray, lengths: np.ndarray, end: np.ndarray, width: int) -> np.ndarray:
    """(N, width) windows of ``records`` (N, R) ending before sample ``end`` (exclusive), clipped to
    each record's valid ``lengths`` (samples before 0 repeat the first one, after the end the last)."""
    idx = np.asarray(end)[:, None] - width + np.arange(width)[None, :]
    idx = np.clip(idx, 0, np.asarray(lengths)[:, None] - 1)
    return np.take_along_axis(records, np.clip(idx, 0, records.shape[1] - 1), axis=1).astype(np.float32)


def press_profile(time_s: np.ndarray, force: np.ndarray, filter_s: float = FORCE_FILTER_S) -> np.ndarray | None:
    """The force record median-filtered over ``filter_s`` (dropouts and the dead band removed) and
    divided by its plateau (the median of the filtered force where it exceeds a quarter of its
    maximum): 0 before the press, ~1 while pressed, whatever the force's unit. ``None`` when the
    record holds no press (no positive force) or has fewer than 3 samples."""
    t = np.asarray(time_s, dtype=np.float64)
    f = np.asarray(force, dtype=np.float64)
    if len(t) < 3:
        return None
    fs = 1.0 / float(np.median(np.diff(t)))
    size = max(1, round(filter_s * fs)) | 1  # odd: centred
    smooth = median_filter(f, size=size, mode="nearest")
    top = float(smooth.max())
    if not top > 0:
        return None
    plateau = float(np.median(smooth[smooth >= 0.25 * top]))
    return np.asarray(smooth / plateau)


def press_onset(time_s: np.ndarray, force: np.ndarray, filter_s: float = FORCE_FILTER_S) -> float | None:
    """The contact onset read from a force record: the time the press crosses half its plateau.

    A median filter of ``filter_s`` removes dropouts (a force sensor with a dead band reads 0, then
    jumps to its first level, and may toggle between them while the contact builds up); the plateau
    is the median of the filtered force where it exceeds a quarter of its maximum; the onset is the
    first crossing of half the plateau, interpolated between samples (:func:`press_profile`). Why
    half the plateau and not the first touch: the first touch hides in the dead band and the
    dropouts (some records start already in light contact), while the middle of the rise is where
    the force changes fastest, so its time is the least sensitive to noise, and it is unit-free (the
    force may be in any unit). Thermal contact starts a little earlier (at the first touch: up to
    ~1 s for a slow press). Returns ``None`` when the record holds no press (no positive force) or
    starts above half the plateau (the onset is before the record).
    """
    t = np.asarray(time_s, dtype=np.float64)
    profile = press_profile(t, force, filter_s)
    if profile is None:
        return None
    above = profile >= 0.5
    i = int(np.argmax(above))
    if i == 0:
        return None
    lo, hi = profile[i - 1], profile[i]
    frac = (0.5 - lo) / (hi - lo) if hi > lo else 1.0  # hi >= 0.5 > lo
    return float(t[i - 1] + frac * (t[i] - t[i - 1]))
