"""One curve's onset alignment: :func:`~tactile_learn.thermal_signal.detect_onset` and
:func:`~tactile_learn.thermal_signal.drop_segments` for a single window, the streaming case.

The batch functions work on (B, W) arrays with a mask per step (spans, crossings, the padded run's
second reading), about 150 numpy calls whatever B is: at B = 1 those calls are the whole cost.
Here the same steps are slices and scalars of one (W,) curve, with the batch version's arithmetic
(the same sums over the same zero-padded rows, the same median), so the results are equal to the
batch path's, bit for bit (tests/tactile_learn/estimators/test_frame_paths.py checks this on many
curves, padded and noise-free ones included).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tactile_learn.thermal_signal import _TRIM_FACTOR, LOOKBACK

__all__ = ["CurveOnset", "detect_onset_one", "drop_segment_one"]


@dataclass(frozen=True)
class CurveOnset:
    """:class:`~tactile_learn.thermal_signal.Onset` of one curve, as Python scalars."""

    index: int  # k0: last baseline sample; W - 1 when nothing was detected
    detected: bool
    baseline: float  # degC
    sigma: float  # K
    direction: float  # +1 the pixel cools on contact, -1 it warms


def _span_median(x: np.ndarray, start: int, stop: int) -> float:
    """numpy's median of ``x[start:stop]`` (NaN when empty), as the batch ``_span_median``."""
    span = np.sort(x[start:stop])
    count = len(span)
    if count == 0:
        return math.nan
    lo, hi = span[(count - 1) // 2], span[count // 2]
    return float(lo if count % 2 == 1 else (lo + hi) / 2.0) + 0.0


def _detect_from(x: np.ndarray, start: int, stop: int, n0: int, adc_step: float) -> tuple[CurveOnset, int]:
    """The batch ``_detect_from`` on one curve: the onset and the first threshold crossing ``k1``."""
    w = len(x)
    b0 = _span_median(x, start, min(start + n0, stop))
    if not math.isfinite(b0):
        b0 = float(x[-1])
    floor = max(adc_step / math.sqrt(12.0), 1e-3)
    # successive differences inside [start, min(start + 2 n0, stop)), summed over the zero-padded
    # row as the batch version sums them (the same rounding)
    end = min(start + 2 * n0, stop, w)
    count = max(end - 1 - start, 0)
    d2 = np.zeros(w - 1)
    if count:
        d2[start : end - 1] = np.diff(x[start:end]) ** 2
    trimmed = (float(d2.sum()) - float(d2.max(initial=0.0))) / max(count - 1, 1)
    sigma0 = max(math.sqrt(trimmed / (2.0 * _TRIM_FACTOR)) if count >= 3 else 0.0, floor)
    tail = float(x[-min(3, w) :].mean())
    direction = 1.0 if tail <= b0 else -1.0
    dev = direction * (b0 - x)
    above = dev > max(5.0 * sigma0, 2.0 * adc_step)
    both = above.copy()
    both[:-1] &= above[1:]
    k1 = int(both.argmax())
    detected = bool(both[k1])
    if not detected:
        return CurveOnset(w - 1, False, _baseline(x, w - 1, b0), sigma0, direction), w - 1
    quiet = np.flatnonzero(dev[:k1] <= 1.5 * sigma0)
    k0 = int(quiet[-1]) if len(quiet) else max(k1 - 1, 0)
    return CurveOnset(k0, True, _baseline(x, k0, b0), sigma0, direction), k1


def _baseline(x: np.ndarray, k0: int, b0: float) -> float:
    """The mean of the samples before ``k0 - 1`` (at least 3, else ``b0``), summed over the
    zero-padded row as the batch version sums it."""
    upto = max(k0 - 1, 0)
    if upto < 3:
        return b0
    padded = x.copy()
    padded[upto:] = 0.0
    return float(padded.sum()) / upto


def detect_onset_one(x: np.ndarray, fs: float, adc_step: float = 0.0, base_s: float = 0.1) -> CurveOnset:
    """:func:`~tactile_learn.thermal_signal.detect_onset` of one curve ``x`` (W,)."""
    x = np.asarray(x, dtype=np.float64)
    w = len(x)
    differs = x != x[0]
    flat = int(differs.argmax()) if differs.any() else w  # leading samples equal to the first
    start = flat - 1 if flat >= 3 else 0
    n0 = int(min(max(3, round(base_s * fs)), max(1, w // 2)))
    onset, _ = _detect_from(x, start, w, n0, adc_step)
    if start == 0:
        return onset
    # the padded run may be a noise-free baseline: the batch version's second reading
    plain, k1 = _detect_from(x, 0, flat, n0, adc_step)
    if not plain.detected:
        return onset
    end = flat - 1
    dev = plain.direction * (x[0] - x)
    back = bool((dev[k1:] <= 1.5 * plain.sigma).any())
    rise = np.diff(dev, prepend=0.0)
    stall = bool((rise[end + 1 : end + 2 + LOOKBACK] <= 0).any())
    return plain if k1 <= end + LOOKBACK and not back and not stall else onset


def drop_segment_one(x: np.ndarray, onset: CurveOnset, lookback: int = LOOKBACK) -> tuple[np.ndarray, int]:
    """:func:`~tactile_learn.thermal_signal.drop_segments` of one curve: the drop ``y`` (J + W,)
    aligned at the onset (zero past the window's end) and its number of valid entries."""
    x = np.asarray(x, dtype=np.float64)
    w = len(x)
    y = np.zeros(lookback + w)
    first = onset.index - lookback  # the sample y[0] reads
    lo = max(first, 0)
    y[lo - first : w - first] = onset.direction * (onset.baseline - x[lo:])
    return y, lookback + w - onset.index
