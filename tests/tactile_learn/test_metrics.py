"""tactile_learn.metrics: the strip-map metrics every report quotes (eval, bench, model cards)."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_learn.metrics import find_peaks, pearson_per_frame, strip_map_metrics


def blob(shape: tuple[int, int], centre: tuple[float, float], width: float = 0.8, height: float = 1.0) -> np.ndarray:
    """A Gaussian bump centred at (row, col) in cell units."""
    rows, cols = np.mgrid[: shape[0], : shape[1]].astype(np.float64)
    return height * np.exp(-((rows - centre[0]) ** 2 + (cols - centre[1]) ** 2) / (2 * width**2))


@pytest.fixture()
def maps(rng: np.random.Generator) -> np.ndarray:
    return rng.random((5, 8, 7))


def test_pearson_is_one_for_any_positive_affine_copy_and_minus_one_for_a_negated_one(maps: np.ndarray) -> None:
    np.testing.assert_allclose(pearson_per_frame(maps, maps), 1.0, atol=1e-12)
    np.testing.assert_allclose(pearson_per_frame(3.0 * maps + 2.0, maps), 1.0, atol=1e-12)
    np.testing.assert_allclose(pearson_per_frame(-maps, maps), -1.0, atol=1e-12)


def test_pearson_matches_numpy_corrcoef_frame_by_frame(maps: np.ndarray, rng: np.random.Generator) -> None:
    pred = maps + rng.normal(0, 0.3, maps.shape)
    expected = [np.corrcoef(p.ravel(), t.ravel())[0, 1] for p, t in zip(pred, maps, strict=True)]
    np.testing.assert_allclose(pearson_per_frame(pred, maps), expected, rtol=1e-10)


def test_pearson_excludes_constant_truth_and_scores_a_constant_estimate_zero(maps: np.ndarray) -> None:
    truth = maps.copy()
    truth[1] = 0.0  # no contact: no correlation to speak of
    pred = maps.copy()
    pred[2] = 0.7  # a flat estimate of a varying truth
    r = pearson_per_frame(pred, truth)
    assert np.isnan(r[1])
    assert r[2] == pytest.approx(0.0, abs=1e-9)
    assert np.all(np.isfinite(np.delete(r, 1)))


def test_nrmse_is_zero_for_the_truth_and_one_for_an_all_zero_estimate(maps: np.ndarray) -> None:
    assert strip_map_metrics(maps, maps, pitch_mm=5.0)["nrmse"] == pytest.approx(0.0, abs=1e-12)
    assert strip_map_metrics(np.zeros_like(maps), maps, pitch_mm=5.0)["nrmse"] == pytest.approx(1.0)
    # twice the truth: the error is the truth itself
    assert strip_map_metrics(2 * maps, maps, pitch_mm=5.0)["nrmse"] == pytest.approx(1.0)


@pytest.mark.parametrize("centre", [(3.0, 2.0), (3.3, 2.6), (5.8, 1.2)])
def test_a_single_peak_is_found_near_its_sub_cell_centre(centre: tuple[float, float]) -> None:
    (peaks,) = find_peaks(blob((9, 8), centre)[None])
    assert peaks.shape == (1, 2)
    # the 3 x 3 centroid is biased towards the cell centre, by far less than half a cell
    assert np.abs(peaks[0] - np.array(centre)).max() < 0.35


def test_peaks_below_a_quarter_of_the_maximum_are_not_peaks() -> None:
    field = blob((10, 10), (2.0, 2.0)) + blob((10, 10), (7.0, 7.0), height=0.2)
    assert len(find_peaks(field[None])[0]) == 1
    field = blob((10, 10), (2.0, 2.0)) + blob((10, 10), (7.0, 7.0), height=0.5)
    assert len(find_peaks(field[None])[0]) == 2
    assert len(find_peaks(np.zeros((1, 4, 4)))[0]) == 0  # no contact, no peak


def test_peak_error_is_the_shift_in_mm_and_a_missing_estimate_counts_as_a_miss() -> None:
    truth = np.stack([blob((12, 12), (4.0, 4.0)), blob((12, 12), (6.0, 5.0))])
    shifted = np.stack([blob((12, 12), (4.0, 6.0)), blob((12, 12), (6.0, 5.0))])
    metrics = strip_map_metrics(shifted, truth, pitch_mm=2.5)
    assert metrics["peak_err_mm_mean"] == pytest.approx((2 * 2.5 + 0.0) / 2, abs=0.05)
    assert metrics["peak_miss_rate"] == 0.0
    empty = shifted.copy()
    empty[0] = 0.0
    missed = strip_map_metrics(empty, truth, pitch_mm=2.5)
    assert missed["peak_miss_rate"] == pytest.approx(0.5)
    assert missed["n_frames_with_contact"] == 2


def test_metrics_refuse_mismatched_shapes(maps: np.ndarray) -> None:
    with pytest.raises(ValueError, match="differs from truth"):
        strip_map_metrics(maps[:, :-1], maps, pitch_mm=5.0)
