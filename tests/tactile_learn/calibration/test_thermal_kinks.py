"""Kinks in a residual (tactile_learn.calibration.thermal_kinks): slope changes placed at known
instants are found there, a smooth residual has none, and hinges at them explain what they are."""

from __future__ import annotations

import numpy as np

from tactile_learn.calibration.thermal_kinks import residual_kinks, residual_windows

FS = 20.0


def _records(kinks: list[tuple[float, float]], noise_k: float, seed: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 7.0, 1 / FS)
    onset = 0.3
    tt = t - onset
    heated = 0.004 * np.sin(0.5 * tt)  # a slow, smooth misfit: no kink
    for at, change in kinks:
        heated = heated + change * np.maximum(tt - at, 0.0)
    passive = 0.002 * np.cos(0.3 * tt)
    res = np.stack([heated, passive])[:, None, :] + rng.normal(0.0, noise_k, (2, 1, len(t)))
    return res, t[None, :], np.ones((1, len(t)), dtype=bool), np.array([onset])


def test_kinks_are_found_where_they_are() -> None:
    res, t, mask, onset = _records([(1.5, -0.06), (3.2, 0.08)], 4e-4, 0)
    out = residual_kinks(res, t, mask, onset, FS, ("heated", "passive"))
    found = out["touches"][0]["heated"]
    assert len(found) == 2 and np.allclose([k["t_s"] for k in found], [1.5, 3.2], atol=0.051)
    assert np.allclose([k["slope_change_k_s"] for k in found], [-0.06, 0.08], rtol=0.25)
    assert out["touches"][0]["passive"] == [] and out["touches"][0]["heated_kinks_on_both"] == 0
    h = out["heated"]
    assert h["kinks"] == 2
    # hinges at the kinks leave the slow misfit and the noise: far less than a line alone
    assert h["late_rms_about_a_line_and_hinges_k"] < 0.3 * h["late_rms_about_a_line_k"]
    assert h["rms_away_from_kinks_k"] <= h["rms_k"] * 1.05


def test_a_smooth_residual_has_no_kinks() -> None:
    res, t, mask, onset = _records([], 4e-4, 1)
    out = residual_kinks(res, t, mask, onset, FS, ("heated", "passive"))
    assert out["heated"]["kinks"] == 0 and out["passive"]["kinks"] == 0
    assert out["heated"]["late_rms_about_a_line_and_hinges_k"] == out["heated"]["late_rms_about_a_line_k"]


def test_residual_windows_say_where_the_squares_are() -> None:
    """A residual that is large only in the first half second after the onset has its squares there."""
    t = np.arange(0.0, 7.0, 1 / FS)[None, :]
    onset = np.array([0.3])
    rel = t - onset[:, None]
    res = np.where((rel >= 0.0) & (rel < 0.5), 0.02, 0.001)[None] * np.ones((2, 1, 1))
    out = residual_windows(res, t, np.ones_like(t, dtype=bool), onset, ("heated", "passive"))
    rows = out["heated"]
    assert [r["from_s"] for r in rows] == [None, 0.0, 0.5, 1.0, 2.0, 4.0]
    assert sum(r["samples"] for r in rows) == t.shape[1]
    assert np.isclose(sum(r["share_of_squares"] for r in rows), 1.0)
    assert rows[1]["share_of_squares"] > 0.8 and np.isclose(rows[1]["rms_k"], 0.02)
    assert np.isclose(rows[0]["rms_k"], 0.001) and rows[0]["samples"] == 6
