"""scripts/thermal_floor.py's measures on curves whose answer is known: what a smooth spline leaves
of white noise and of a slow curve, and the repeatability of touches that differ only by a
time shift and scale and an amplitude gain and offset (nothing left after the affine map)."""

from __future__ import annotations

import sys

import numpy as np

from tactile_learn.thermal_recordings import Touch
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import thermal_floor


def test_a_smooth_spline_leaves_white_noise_and_follows_a_slow_curve() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 5.0, 1.0 / 200.0)
    slow = 0.3 * np.exp(-t / 1.5)
    noise = rng.normal(0.0, 1e-4, t.shape)
    assert thermal_floor.smooth_fit_rms(slow, t, 1.0) < 2e-5  # of a 0.3 K curve: 1 part in 15,000
    assert abs(thermal_floor.smooth_fit_rms(slow + noise, t, 1.0) / 1e-4 - 1) < 0.05


def _touch(shift: float, scale: float, gain: float, level: float, rng: np.random.Generator) -> Touch:
    t = np.arange(0.0, 9.0, 1.0 / 200.0)
    onset = 1.2
    u = (t - onset - shift) / scale
    shape = np.where(u < 0, 0.0, -((1 - np.exp(-np.maximum(u, 0) / 1.3)) ** 2))
    heated = level + gain * 2.0 * shape + rng.normal(0.0, 1e-5, t.shape)
    return Touch("x.csv", t, heated, passive_c=22.0 + 0.5 * shape, onset_s=onset)


def test_repeatability_affine_map_removes_time_and_amplitude_differences() -> None:
    rng = np.random.default_rng(1)
    touches = [
        _touch(0.0, 1.0, 1.0, 29.5, rng),
        _touch(0.05, 1.08, 0.9, 29.6, rng),
        _touch(-0.04, 0.95, 1.1, 29.4, rng),
    ]
    out = thermal_floor.repeatability(touches, [1.2, 1.2, 1.2], "heated")
    assert out["all_raw"] > 0.05  # tens of mK apart as recorded
    assert out["all_affine"] < 0.05 * out["all_raw"]  # nothing left but a little of the map's reach
    assert len(out["raw"]) == len(thermal_floor.WINDOWS)
    # a touch of another shape is not mapped away
    odd = _touch(0.0, 1.0, 1.0, 29.5, rng)
    odd.temperature_c = odd.temperature_c + 0.02 * np.sin(odd.time_s)
    out2 = thermal_floor.repeatability([*touches[:2], odd], [1.2, 1.2, 1.2], "heated")
    assert out2["all_affine"] > 5 * out["all_affine"]
