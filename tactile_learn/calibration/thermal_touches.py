"""Labelled touches on the thermal calibration's fitting grid, and the recorder's noise levels.

:func:`prepare_touches` resamples each record to :data:`FIT_HZ` from :data:`PRE_S` before its onset;
:func:`noise_levels` measures what a calibration's residual is reported against (white noise,
time-stamp jitter and the pre-contact scatter; see :mod:`.thermal_calibration`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import LSQUnivariateSpline

from synth.errors import DataError

__all__ = ["FIT_HZ", "PRE_S", "QUIET_BEFORE_S", "FitTouch", "noise_levels", "prepare_touches"]

#: rate (Hz) the curves are fitted at: the curves are smooth (lags of tenths of a second)
FIT_HZ = 20.0
#: the fit starts this long before the onset (earlier samples hold the heater's settling)
PRE_S = 0.3
#: the noise's pre-contact segment ends this long before the onset (a press's first touch comes
#: ~0.3 s before its force's half-plateau crossing on the robot recordings)
QUIET_BEFORE_S = 0.5


@dataclass
class FitTouch:
    """One labelled touch on the fitting grid: times ``t`` (s, record time), channels (degC),
    the onset (s, record time) and the class index."""

    file: str
    label: int
    t: np.ndarray
    heated: np.ndarray
    passive: np.ndarray | None
    onset_s: float


def prepare_touches(
    series: Sequence[tuple[str, int, np.ndarray, np.ndarray, np.ndarray | None, float]], fs: float = FIT_HZ
) -> list[FitTouch]:
    """Resample ``(file, label, time_s, heated, passive, onset_s)`` records to ``fs`` from
    ``PRE_S`` before the onset (or the record's start) to the record's end."""
    out = []
    for file, label, time_s, heated, passive, onset in series:
        start = max(float(time_s[0]), onset - PRE_S)
        grid = start + np.arange(math.floor((float(time_s[-1]) - start) * fs + 1e-9) + 1) / fs
        if grid[-1] - onset < 1.0:
            raise DataError(f"{file}: less than 1 s of contact after the onset ({onset:.3f} s): too short to calibrate")
        out.append(
            FitTouch(
                file,
                label,
                grid,
                np.interp(grid, time_s, heated),
                None if passive is None else np.interp(grid, time_s, passive),
                onset,
            )
        )
    return out


def noise_levels(series: Sequence[tuple[np.ndarray, np.ndarray, float]]) -> dict[str, float]:
    """White noise and timing jitter of records ``(time_s, values, onset_s)`` (one channel).

    Each record is smoothed by a least-squares cubic spline with knots every 0.25 s (which follows
    every physical change of these sensors); ``sigma_w`` is the RMS of what it leaves before the
    onset, ``sigma_t`` the median over records of that remainder's RMS divided by the slope's RMS
    where the curve moves faster than 0.1 K/s (time-stamp jitter moves a sample by ``slope * dt``),
    ``precontact_k`` the median scatter of the segment before any contact about a quadratic trend
    (the noise's whole variance per sample, correlated parts included; see
    :func:`~tactile_learn.calibration.thermal_report.residual_summary`).
    """
    white, jitter, pre_scatter = [], [], []
    for t, x, onset in series:
        # before any contact: the scatter about a quadratic trend (the heater's settling), every
        # correlated component up to the segment's length
        quiet = (t > t[0] + 0.05) & (t < onset - QUIET_BEFORE_S)
        if quiet.sum() >= 20:
            tq = t[quiet] - t[quiet].mean()
            trend = np.polyval(np.polyfit(tq, x[quiet], 2), tq)
            pre_scatter.append(float(np.sqrt(np.mean((x[quiet] - trend) ** 2))))
        knots = np.arange(t[0] + 0.25, t[-1] - 0.2, 0.25)
        if len(knots) < 4:
            continue
        spline = LSQUnivariateSpline(t, x, knots, k=3)
        rest = x - spline(t)
        slope = spline.derivative()(t)
        pre = (t < onset - 0.1) & (t > t[0] + 0.1)
        if pre.sum() >= 20:
            white.append(float(np.sqrt(np.mean(rest[pre] ** 2))))
        moving = np.abs(slope) > 0.1
        if moving.sum() >= 50:
            jitter.append(float(np.sqrt(np.mean(rest[moving] ** 2) / np.mean(slope[moving] ** 2))))
    return {
        "white_k": float(np.median(white)) if white else 1e-3,
        "timing_jitter_s": float(np.median(jitter)) if jitter else 0.0,
        "precontact_k": float(np.median(pre_scatter)) if pre_scatter else (float(np.median(white)) if white else 1e-3),
    }
