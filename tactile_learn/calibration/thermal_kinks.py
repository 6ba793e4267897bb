"""Kinks in a calibration's residual: sudden changes of its slope at a few instants of a touch.

A smooth model (lags, a contact, an object) cannot follow a curve whose slope changes within a
few samples at a random instant (on the robot recordings: a contact that changes without its force
changing, felt by both thermistors at once). :func:`residual_kinks` finds them and says how much of
the residual they are: the slope change about every sample (lines fitted over ``HALF_S`` each
side), local maxima above ``THRESHOLD_K_S`` at least ``SEPARATION_S`` apart after ``AFTER_S`` of
contact (the first second holds the press's own transient); per channel the RMS without the
samples within ``EXCLUDE_S`` of a kink, and after ``AFTER_S`` the RMS about a straight line with
and without a hinge (a continuous change of slope) at every kink: the share a discrete event per
kink explains.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np

__all__ = ["WINDOWS_S", "event_times", "kink_indices", "residual_kinks", "residual_windows", "slope_change"]

#: each side's window for the slope about a sample (s)
HALF_S = 0.3
#: a slope change at least this large is a kink (K/s): ~15 times the change white noise of the
#: heated channel (0.4 mK) makes over two 0.3 s windows at 20 Hz, a tenth of the heated drop's
#: slope in its first seconds
THRESHOLD_K_S = 0.03
#: kinks closer than this are one (s)
SEPARATION_S = 0.4
#: kinks are looked for this long after the onset (s): the press's transient comes first
AFTER_S = 0.8
#: the samples this close to a kink are left out of the RMS without them (s)
EXCLUDE_S = 0.1


def slope_change(t: np.ndarray, r: np.ndarray, n: int) -> np.ndarray:
    """Right minus left least-squares slope about every sample (0 within ``n`` of an end)."""
    out = np.zeros_like(r)
    for k in range(n, len(r) - n):
        left = np.polyfit(t[k - n : k + 1], r[k - n : k + 1], 1)[0]
        right = np.polyfit(t[k : k + n + 1], r[k : k + n + 1], 1)[0]
        out[k] = right - left
    return out


def kink_indices(t: np.ndarray, change: np.ndarray) -> list[int]:
    """Indices of the local maxima of ``|change|`` above the threshold, strongest first kept."""
    size = np.abs(change)
    peaks = [
        k
        for k in range(1, len(t) - 1)
        if size[k] >= THRESHOLD_K_S and size[k] >= size[k - 1] and size[k] >= size[k + 1] and t[k] > AFTER_S
    ]
    kept: list[int] = []
    for k in sorted(peaks, key=lambda k: -size[k]):
        if all(abs(t[k] - t[j]) > SEPARATION_S for j in kept):
            kept.append(k)
    return sorted(kept)


def _line_rms(t: np.ndarray, r: np.ndarray, hinges: list[float]) -> np.ndarray:
    """What is left of ``r`` about a line plus hinges ``max(t - t_k, 0)`` (least squares)."""
    cols = np.stack([np.ones_like(t), t, *(np.maximum(t - tk, 0.0) for tk in hinges)], axis=1)
    return r - cols @ np.linalg.lstsq(cols, r, rcond=None)[0]


#: kinks of two channels this close are one contact event (s): 7 of 10 cooled-wood heated kinks on
#: R_1 have a passive one within 0.15 s, and the channels' different lags delay one step's bend by
#: 0.15-0.35 s (simulated), so up to 0.2 s apart
SAME_EVENT_S = 0.3


def event_times(res: np.ndarray, t: np.ndarray, mask: np.ndarray, onset: np.ndarray, fs: float) -> list[list[float]]:
    """Contact events found in residuals ``res`` (C, n, W) (as :func:`residual_kinks`): per touch the
    times (s after the onset) of every channel's kinks, one event where two channels' kinks lie
    within ``SAME_EVENT_S`` (the same slip felt by both thermistors), the stronger one's time."""
    n_side = max(round(HALF_S * fs), 2)
    out = []
    for i in range(res.shape[1]):
        tt = t[i][mask[i]] - onset[i]
        found: list[tuple[float, float]] = []  # (|slope change| relative to the threshold, time)
        for c in range(res.shape[0]):
            change = slope_change(tt, res[c, i][mask[i]], n_side)
            found += [(abs(float(change[k])), float(tt[k])) for k in kink_indices(tt, change)]
        kept: list[float] = []
        for _, time in sorted(found, reverse=True):
            if all(abs(time - other) > SAME_EVENT_S for other in kept):
                kept.append(time)
        out.append(sorted(kept))
    return out


def residual_kinks(
    res: np.ndarray, t: np.ndarray, mask: np.ndarray, onset: np.ndarray, fs: float, channels: tuple[str, ...]
) -> dict[str, Any]:
    """Kinks of residuals ``res`` (C, n, W) at times ``t`` (n, W) (record time; ``mask`` (n, W)
    the samples of each record, ``onset`` (n,) each onset, ``fs`` the rate): per channel the
    number of kinks, the RMS (K) with and without the samples near them, and after ``AFTER_S`` the
    RMS about a line with and without a hinge at each kink; per touch and channel the kinks' times
    (s after the onset) and slope changes (K/s), and how many heated kinks have one on the other
    channel within 0.15 s."""
    n_side = max(round(HALF_S * fs), 2)
    out: dict[str, Any] = {"threshold_k_s": THRESHOLD_K_S, "after_onset_s": AFTER_S, "touches": []}
    sums: dict[str, dict[str, list[np.ndarray]]] = {
        ch: {"all": [], "kept": [], "line": [], "hinged": []} for ch in channels
    }
    for i in range(res.shape[1]):
        tt = t[i][mask[i]] - onset[i]
        row: dict[str, Any] = {}
        times: dict[str, list[float]] = {}
        for c, ch in enumerate(channels):
            r = res[c, i][mask[i]]
            change = slope_change(tt, r, n_side)
            kinks = kink_indices(tt, change)
            times[ch] = [float(tt[k]) for k in kinks]
            row[ch] = [{"t_s": round(float(tt[k]), 3), "slope_change_k_s": float(change[k])} for k in kinks]
            far = np.ones(len(r), dtype=bool)
            for k in kinks:
                far &= np.abs(tt - tt[k]) > EXCLUDE_S
            late = tt > AFTER_S
            sums[ch]["all"].append(r)
            sums[ch]["kept"].append(r[far])
            if late.sum() > 2 + len(kinks):
                sums[ch]["line"].append(_line_rms(tt[late], r[late], []))
                sums[ch]["hinged"].append(_line_rms(tt[late], r[late], times[ch]))
        if len(channels) > 1:
            row["heated_kinks_on_both"] = sum(
                any(abs(a - b) <= 0.15 for b in times[channels[1]]) for a in times["heated"]
            )
        out["touches"].append(row)

    def rms(parts: list[np.ndarray]) -> float:
        return float(np.sqrt(np.mean(np.concatenate(parts) ** 2))) if parts else float("nan")

    for ch in channels:
        s = sums[ch]
        out[ch] = {
            "kinks": sum(len(r[ch]) for r in out["touches"]),
            "rms_k": rms(s["all"]),
            "rms_away_from_kinks_k": rms(s["kept"]),
            "late_rms_about_a_line_k": rms(s["line"]),
            "late_rms_about_a_line_and_hinges_k": rms(s["hinged"]),
        }
    return out


#: the residual's time windows (s after the onset): before the onset (the contact's start), the
#: first second in two halves, then later and later
WINDOWS_S = (-math.inf, 0.0, 0.5, 1.0, 2.0, 4.0, math.inf)


def residual_windows(
    res: np.ndarray, t: np.ndarray, mask: np.ndarray, onset: np.ndarray, channels: tuple[str, ...]
) -> dict[str, Any]:
    """Where the residual is: per channel and time window (:data:`WINDOWS_S`, after each onset) the
    RMS (K), the number of samples and the window's share of the channel's sum of squares."""
    rel = t - onset[:, None]
    out: dict[str, Any] = {}
    for c, ch in enumerate(channels):
        total = float((res[c][mask] ** 2).sum())
        rows = []
        for lo, hi in itertools.pairwise(WINDOWS_S):
            sel = mask & (rel >= lo) & (rel < hi)
            ss = float((res[c][sel] ** 2).sum())
            rows.append(
                {
                    "from_s": None if math.isinf(lo) else lo,
                    "to_s": None if math.isinf(hi) else hi,
                    "samples": int(sel.sum()),
                    "rms_k": math.sqrt(ss / sel.sum()) if sel.any() else float("nan"),
                    "share_of_squares": ss / total if total > 0 else 0.0,
                }
            )
        out[ch] = rows
    return out
