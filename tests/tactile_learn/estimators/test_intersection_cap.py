"""The intersection rule's share cap: a crossing's share of heavily loaded strips stays a finite,
bounded pressure (it was 10^8 kPa where the product rule's share passed 1), on both paths."""

from __future__ import annotations

import numpy as np
import pytest

from synth.errors import ConfigError
from synth.scene import load_scene
from tactile_learn.estimators.classical.intersection import IntersectionEstimator, strip_loads


def _one_row_one_column(level: float) -> np.ndarray:
    """Readings of strips16 with row 3 and column 5 at ``level`` of full scale, the rest unloaded."""
    scene = load_scene("strips16")
    readout = scene.sensor.readout
    frame = np.full((1, 32), readout.offset_v, dtype=np.float32)
    frame[0, [3, 16 + 5]] = level * readout.full_scale_v
    return frame


def test_a_share_above_one_gives_the_capped_pressure_on_both_paths() -> None:
    est = IntersectionEstimator(load_scene("strips16")).prepare()
    frame = _one_row_one_column(0.9)
    rows, cols = strip_loads(est.sensor_, frame.astype(np.float64), est.noise_floor, est.load_floor_)
    share = rows[0, 3] * cols[0, 5] / (0.5 * (rows.sum() + cols.sum()))
    assert share > 1.0  # the case the cap exists for: no crossing can carry it
    cap = float(est.sensor_.law.stress_from_gain(np.array(est.max_share)))
    one = est.predict(frame)
    batch = est.predict(np.repeat(frame, 3, axis=0))
    for maps in (one, batch):
        assert np.all(np.isfinite(maps))
        assert maps[0, 3, 5] == pytest.approx(cap, rel=1e-6)
        assert maps.max() <= cap * (1 + 1e-6)
    np.testing.assert_array_equal(one[0], batch[0])


def test_shares_below_the_cap_are_untouched() -> None:
    est = IntersectionEstimator(load_scene("strips16")).prepare()
    uncapped = IntersectionEstimator(load_scene("strips16"), max_share=1 - 1e-6).prepare()
    frame = _one_row_one_column(0.15)  # loads ~0.6: a share of ~0.6
    assert 0 < est.predict(frame).max() < float(est.sensor_.law.stress_from_gain(np.array(est.max_share)))
    np.testing.assert_array_equal(est.predict(frame), uncapped.predict(frame))


@pytest.mark.parametrize("bad", [0.0, 1.0, -0.5, float("nan")])
def test_a_cap_outside_zero_one_is_refused(bad: float) -> None:
    with pytest.raises(ConfigError, match="max_share"):
        IntersectionEstimator(load_scene("strips16"), max_share=bad).prepare()
