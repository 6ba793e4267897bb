"""The calibrated fit's single curves through the bases factored per contact start: the factors
reproduce every design's basis to the dense product's rounding, and one curve's probabilities equal
the batch path's (dense bases) within 1e-7 on simulated, real (robot recordings) and extreme
curves; the stream's single-curve runner is predict's single-curve path; bad curves are refused."""

from __future__ import annotations

import numpy as np
import pytest

from synth.errors import InputError
from synth.scene import Scene, load_scene
from tactile_learn.estimators.classical.calibrated_fit import CalibratedFitEstimator
from tactile_learn.estimators.classical.calibrated_one_curve import StartFactoredBases
from tactile_learn.estimators.classical.calibrated_one_curve_run import overlapping_windows
from tactile_learn.frame_stream import FrameStream
from tactile_learn.tasks.thermal import ThermalTask
from tests.paths import REPO_ROOT
from tests.tactile_learn.estimators.test_thermal_fits_batch1 import held_out_curves
from tests.tactile_learn.test_thermal_real import robot_scene

ROBOT_DATA = REPO_ROOT.parent / "shared" / "data" / "thermal-robot"
#: probabilities of one curve against the batch's (float32 output: 6e-8 is its rounding near 1)
TOLERANCE = 1e-7


def scene_of(name: str) -> Scene:
    """A shipped scene, the robot fingertip, or the robot with a heater that steps on contact (a
    fifth column per design: the power step's amplitude)."""
    if name.startswith("robot"):
        return robot_scene(**({"sensor.heater": "step"} if name == "robot_step" else {}))  # type: ignore[return-value]
    return load_scene(name)


def one_by_one(est: CalibratedFitEstimator, x: np.ndarray) -> np.ndarray:
    return np.concatenate([est.predict_proba(x[i : i + 1]) for i in range(len(x))])


def assert_single_curves_equal_the_batch(est: CalibratedFitEstimator, x: np.ndarray) -> None:
    assert len(x) > 1  # a batch of one is the single-curve path
    batch, single = est.predict_proba(x), one_by_one(est, x)
    np.testing.assert_allclose(single, batch, rtol=0, atol=TOLERANCE)
    np.testing.assert_array_equal(single.argmax(axis=1), batch.argmax(axis=1))
    labels = [est.predict(x[i : i + 1]) for i in range(len(x))]
    assert all(label.dtype == np.int64 and label.shape == (1,) for label in labels)
    np.testing.assert_array_equal(np.concatenate(labels), est.predict(x))


@pytest.mark.parametrize("scene_name", ["thermal", "thermal_wns", "robot", "robot_step"])
def test_factors_reproduce_every_design_basis(scene_name: str) -> None:
    est = CalibratedFitEstimator(scene_of(scene_name)).prepare()
    q, _, n_columns, _ = est.projections_
    one: StartFactoredBases = est.one_curve_
    _, owner = est.templates_
    _, design_start, design_template = est._design_keys()
    n = q.shape[0]
    n_starts, width, _ = one.second.shape
    rank_of = np.argsort(np.argsort(owner, kind="stable"), kind="stable")  # template -> column in its start
    n_templates = len(owner)
    worst = 0.0
    for g, (s, m) in enumerate(zip(design_start, design_template, strict=True)):
        factor = one.first[:, s * width : (s + 1) * width]
        coordinates = one.second[s][:, rank_of[m] + n_templates * np.arange(n_columns)]
        dense = q[:, g * n_columns : (g + 1) * n_columns]
        worst = max(worst, float(np.abs(factor @ coordinates - dense).max()))
    assert worst <= 4 * n * np.finfo(np.float64).eps
    np.testing.assert_array_equal(one.first[:, n_starts * width :], q[:, -n_columns:])  # the lines' own basis
    # the point: fewer numbers to read per curve than the dense bases (the seed scene: a third)
    assert one.first.size + one.second.size < (0.4 if scene_name == "thermal" else 0.7) * q.size


@pytest.mark.parametrize("scene_name", ["thermal", "thermal_wns", "robot", "robot_step"])
def test_single_curves_equal_the_batch_on_held_out_touches(scene_name: str) -> None:
    scene = scene_of(scene_name)
    est = CalibratedFitEstimator(scene).prepare()
    n_touches = 4 if scene_name.startswith("robot") else 8  # a robot touch: one window; the seed's: 16
    x = held_out_curves(scene, n_touches, seed=61)[:64]
    assert_single_curves_equal_the_batch(est, x)
    assert len(np.unique(est.predict(x))) > 1  # materials told apart, not one answer


def test_single_curves_equal_the_batch_on_extreme_curves() -> None:
    """Flat and linear windows (no contact), large and tiny drops, steps, pure noise, readings near
    the ADC's ends: the factored bases' error grows with |y|^2 as the dense product's rounding does."""
    scene = load_scene("thermal")
    est = CalibratedFitEstimator(scene).prepare()
    lo, hi = scene.sensor.readout.adc_range_c
    w = scene.sensor.window_samples
    t = np.arange(w) / scene.sensor.readout.sampling_hz
    rng = np.random.default_rng(19)
    touch = held_out_curves(scene, 4, seed=62)[:16].astype(np.float64)
    base = touch - touch[:, :1]
    curves = [
        np.full(w, 33.0),  # constant: |y|^2 = 0 after centring
        33.0 + 0.2 * t,  # a drifting baseline
        33.0 + rng.normal(0.0, 0.01, w),  # noise only
        33.0 + np.where(t > 0.9, -4.0, 0.0),  # a step
        *(33.0 + 20.0 * base[:4]),  # 20x the simulated drops
        *(33.0 + 1e-3 * base[4:8]),  # drops far below the noise
        *(hi - 0.5 + 0.01 * base[8:12]),  # near the ADC's top
        *(lo + 0.5 + 5.0 * base[12:16] - 5.0 * base[12:16].min()),  # near its bottom
    ]
    assert_single_curves_equal_the_batch(est, np.asarray(curves, dtype=np.float32))


@pytest.mark.skipif(not (ROBOT_DATA / "touches.csv").is_file(), reason=f"no thermal-robot recordings at {ROBOT_DATA}")
def test_single_curves_equal_the_batch_on_the_robot_recordings() -> None:
    scene = robot_scene()
    task = ThermalTask()
    x = np.asarray(task.latency_inputs(task.load_eval_data(ROBOT_DATA, scene)), dtype=np.float32)  # type: ignore[arg-type]
    assert x.shape[0] == 90
    assert_single_curves_equal_the_batch(CalibratedFitEstimator(scene).prepare(), x)  # type: ignore[arg-type]


def test_stream_runner_is_the_single_curve_path_and_leaves_its_input_alone() -> None:
    scene = load_scene("thermal")
    est = CalibratedFitEstimator(scene).prepare()
    x = held_out_curves(scene, 2, seed=63)[:20]
    stream = FrameStream(est)
    streamed = np.concatenate([stream.predict(x[i : i + 1]) for i in range(len(x))])
    np.testing.assert_array_equal(streamed, one_by_one(est, x))
    curve = x[:1].astype(np.float64)
    kept = curve.copy()
    for call in (est.predict_proba_checked, est.frame_runner()):
        call(curve)
        np.testing.assert_array_equal(curve, kept)  # the curve is centred in a copy


@pytest.mark.parametrize(("kind", "message"), [("nan", "NaN"), ("inf", "NaN or inf"), ("shape", "expected shape")])
def test_bad_single_curves_are_refused(kind: str, message: str) -> None:
    scene = load_scene("thermal")
    est = CalibratedFitEstimator(scene).prepare()
    curve = held_out_curves(scene, 1, seed=64)[:1].copy()
    if kind == "shape":
        curve = curve[:, :-1]
    else:
        curve[0, 9] = np.nan if kind == "nan" else np.inf
    for call in (est.predict, est.predict_proba, FrameStream(est).predict):
        with pytest.raises(InputError, match=message):
            call(curve)


@pytest.mark.parametrize(
    ("value", "message"),
    [(100.0, "saturated reading at or above"), (0.0, "saturated reading at or below"), (-1.0, "negative")],
)
def test_curves_at_or_beyond_the_adc_range_are_refused(value: float, message: str) -> None:
    """The single-curve path's check (the mean +- |y - mean| inside the range) lets no reading at
    or beyond the ADC's ends through: the full check's error, from every entry point."""
    scene = load_scene("thermal")
    est = CalibratedFitEstimator(scene).prepare()
    curve = held_out_curves(scene, 1, seed=65)[:1].copy()
    curve[0, 40] = value
    assert est.one_frame_run()(curve) is None
    for call in (est.predict, est.predict_proba, FrameStream(est).predict):
        with pytest.raises(InputError, match=message):
            call(curve)


def test_one_frame_run_scores_plain_curves_and_leaves_the_rest_to_the_full_check() -> None:
    scene = load_scene("thermal")
    est = CalibratedFitEstimator(scene).prepare()
    run = est.one_frame_run()
    lo, hi = scene.sensor.readout.adc_range_c
    x = held_out_curves(scene, 2, seed=66)[:8]
    for curve in x:
        out = run(curve[None])
        assert out is not None and out.dtype == np.float32 and out.shape == (1, len(scene.sensor.class_names) + 1)
        np.testing.assert_array_equal(out, est.frame_runner()(curve[None]))
    assert run(x[:2]) is None  # two curves: the batch path
    assert run(x[:1].astype(np.float64)) is None  # another dtype: the full check converts it
    assert run(list(x[:1])) is None
    # valid readings whose mean +- |y - mean| reaches past the range: checked by their extremes
    wide = np.full((1, x.shape[1]), 0.5 * (lo + hi), dtype=np.float32)
    wide[0, 0], wide[0, 1] = np.nextafter(np.float32(lo), np.float32(hi)), np.nextafter(np.float32(hi), np.float32(lo))
    scored = run(wide)
    assert scored is not None
    np.testing.assert_allclose(scored, est.predict_proba(np.concatenate([wide, x[:1]]))[:1], rtol=0, atol=TOLERANCE)


@pytest.mark.parametrize("seed", [0, 1, 2])
def testoverlapping_windows_hold_every_block_whole(seed: int) -> None:
    """The single-curve path's second stage: blocks of uneven height stored as overlapping windows
    of one buffer; a window's product with coordinates that are zero outside its block's rows is
    the block's product, and the buffer is smaller than blocks zero-padded to the window."""
    rng = np.random.default_rng(seed)
    width, columns = 12, 7
    heights = rng.integers(3, width + 1, size=9)
    heights[0] = width
    blocks = [rng.normal(size=(h, columns)) for h in heights]
    windows, placed = overlapping_windows(blocks, width)
    assert windows.shape == (len(blocks), width, columns) and not windows.flags.writeable
    assert sorted(b for b, _ in placed) == list(range(len(blocks)))
    coordinates = np.zeros((len(blocks), 1, width))
    for window, (b, offset) in enumerate(placed):
        np.testing.assert_array_equal(windows[window, offset : offset + heights[b]], blocks[b])
        coordinates[window, 0, offset : offset + heights[b]] = rng.normal(size=heights[b])
    products = np.matmul(coordinates, windows)
    for window, (b, offset) in enumerate(placed):
        expected = coordinates[window, 0, offset : offset + heights[b]] @ blocks[b]
        np.testing.assert_allclose(products[window, 0], expected, rtol=1e-13, atol=1e-13)
    buffer_rows = (len(blocks) - 1) * (windows.strides[0] // windows.strides[1]) + width
    assert buffer_rows < len(blocks) * width
