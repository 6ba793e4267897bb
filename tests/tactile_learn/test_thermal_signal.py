"""The thermal signal module: onset detection's baseline median, onsets in seconds, old import paths."""

from __future__ import annotations

import warnings

import numpy as np

from tactile_learn import thermal_recordings, thermal_signal
from tactile_learn.estimators.classical import curve_match
from tactile_learn.thermal_signal import _span_median, detect_onset, onset_seconds


def test_span_median_is_numpys_nanmedian_bit_for_bit() -> None:
    rng = np.random.default_rng(3)
    for trial in range(2000):
        b, w = int(rng.integers(1, 6)), int(rng.integers(1, 30))
        x = rng.normal(size=(b, w))
        if trial % 3 == 0:  # quantised readings: ties, and -0.0 after rounding
            x = np.round(x * 4) / 4
        start = rng.integers(0, w, size=b)
        stop = np.minimum(start + rng.integers(0, 10, size=b), rng.integers(0, w + 1, size=b))
        idx = np.arange(w)[None, :]
        span = (idx >= start[:, None]) & (idx < stop[:, None])
        with warnings.catch_warnings():  # empty spans: all-NaN rows
            warnings.simplefilter("ignore", RuntimeWarning)
            expected = np.nanmedian(np.where(span, x, np.nan), axis=1)
        assert _span_median(x, start, stop).tobytes() == expected.tobytes()


def test_onset_seconds_is_the_middle_of_the_detected_step() -> None:
    fs = 50.0
    t = np.arange(200) / fs
    curve = 35.0 - np.where(t >= 1.0, 2.0 * (1 - np.exp(-(t - 1.0) / 0.3)), 0.0)
    noise = np.random.default_rng(0).normal(0, 0.005, size=(3, 200))
    records = curve[None, :] + noise
    records[2] = 35.0 + noise[2]  # no contact
    onset = detect_onset(records, fs, 0.0)
    seconds, detected = onset_seconds(records, fs)
    assert detected.tolist() == [True, True, False]
    np.testing.assert_array_equal(seconds[:2], (onset.index[:2] + 0.5) / fs)
    assert seconds[2] == 0.0
    assert np.all(np.abs(seconds[:2] - 1.0) < 0.1)


def test_old_import_paths_still_work() -> None:
    assert curve_match.detect_onset is thermal_signal.detect_onset
    assert thermal_recordings.press_onset is thermal_signal.press_onset
    assert thermal_recordings.press_profile is thermal_signal.press_profile
