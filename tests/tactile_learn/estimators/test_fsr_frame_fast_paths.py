"""FSR single frames, fifth pass: the plain-frame run (``one_frame_run``: the code look-up is the
check) answers plain frames only and streams use it; the one-frame check's conductance keeps the
film's arithmetic bit for bit through its shortcuts (load table by column, no clamps below the
grids' start, the gate exactly 1 far above the break); the refinement's start takes its log in
float64 on both paths."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from synth.scene import load_scene
from synth.sensors import fsr
from tactile_learn.estimators.classical.triangulation import FittedTriangulationEstimator, TriangulationEstimator
from tactile_learn.frame_stream import FrameStream
from tactile_learn.fsr_check import _log_force, one_press_check
from tactile_learn.fsr_one_frame import OneFrameCheck
from tactile_learn.fsr_one_frame import _log_force as one_log_force

SCENE = load_scene("fsr6")


def _frames(n: int = 300, seed: int = 404) -> np.ndarray:
    readings = fsr.make_simulator(SCENE).simulate(n, np.random.default_rng(seed))["readings"]
    return np.ascontiguousarray(readings, dtype=np.float32)


@pytest.mark.parametrize("cls", [TriangulationEstimator, FittedTriangulationEstimator])
def test_the_plain_frame_run_answers_plain_frames_only(cls: type[TriangulationEstimator]) -> None:
    est = cls(SCENE).prepare()
    run = est.one_frame_run()
    frames = _frames()
    batch = est.predict(frames)
    got = np.concatenate([run(frames[i : i + 1]) for i in range(len(frames))])
    np.testing.assert_array_equal(got[:, 3:], batch[:, 3:])
    np.testing.assert_allclose(got, batch, rtol=1e-6, atol=1e-5)
    assert got.dtype == np.float32 and got.shape == (len(frames), 6)
    frame = frames[:1]
    for other in (frame.astype(np.float64), frame[0], frames[:2], frame.tolist()):
        assert run(other) is None  # another type, dtype or shape: the general path
    for code in (np.nan, np.inf, -1.0, 1023.0, 12.5):  # not a key: the general check decides
        bad = frame.copy()
        bad[0, 1] = code
        assert run(bad) is None


def test_a_stream_runs_the_estimators_plain_frame_path() -> None:
    est = TriangulationEstimator(SCENE).prepare()
    stream = FrameStream(est)
    assert stream._run_one is not None
    frames = _frames(120, 405)
    streamed = np.concatenate([stream.predict(frames[i : i + 1]) for i in range(len(frames))])
    np.testing.assert_array_equal(streamed, np.concatenate([est.predict(frames[i : i + 1]) for i in range(120)]))
    assert stream.frames == len(frames)


def _plain_conductance(check: OneFrameCheck, x: float, y: float, log_force: float) -> tuple[list[float], list[float]]:
    """The check's forward model written plainly (clamps, logistic and table rows as the batch
    path has them): the reference the shortcuts must match bit for bit; and each sensor's gate
    argument ``z``."""
    force = math.exp(min(max(log_force, -10.0), 6.0))
    radius = (3.0 * force * check.tip / (4.0 * check.e_star)) ** (1.0 / 3.0)
    ai = min(max((radius - check.a0) / check.da, 0.0), check.a_top)
    j0 = int(ai)
    fj = ai - j0
    gj = 1 - fj
    out, zs = [], []
    for px, py in check.positions:
        dx, dy = x - px, y - py
        d = math.sqrt(dx * dx + dy * dy)
        assert d <= check.d_max
        di = min(max((d - check.d0) / check.dd, 0.0), check.d_top)
        i0 = int(di)
        fi = di - i0
        gi = 1 - fi
        row, nxt = check.table[i0], check.table[i0 + 1]
        per_newton = row[j0] * gi * gj + nxt[j0] * fi * gj + row[j0 + 1] * gi * fj + nxt[j0 + 1] * fi * fj
        load = max(per_newton * force, 0.0)
        z = (load - check.break_n) / check.width_n
        gate = 1.0 / (1.0 + math.exp(-z))
        out.append(check.leak + check.per_n * (check.sat_n * math.tanh(load * gate / check.sat_n)))
        zs.append(z)
    return out, zs


def test_the_checks_conductance_keeps_the_films_arithmetic_bit_for_bit() -> None:
    check = one_press_check(SCENE).prepare().one_frame
    rng = np.random.default_rng(9)
    # on and near the sensors, across the film, light to clipped forces
    points = np.column_stack([rng.uniform(-40.0, 40.0, (4000, 2)), rng.uniform(-12.0, 8.0, 4000)])
    sensors = np.array(check.positions)[rng.integers(0, 6, 500)]
    near = np.column_stack([sensors + rng.normal(0.0, 0.3, (500, 2)), rng.uniform(-1.0, 3.0, 500)])
    zs = []
    for x, y, log_force in np.concatenate([points, near]).tolist():
        want, z = _plain_conductance(check, x, y, log_force)
        assert check.conductance(x, y, log_force) == want
        zs.extend(z)
    # both branches of the gate, and loads just either side of where it is exactly 1
    assert (np.array(zs) > 37.0).sum() > 1000 and (np.array(zs) <= 37.0).sum() > 1000
    assert ((np.array(zs) > 30.0) & (np.array(zs) < 45.0)).sum() > 20


def test_the_starts_log_is_float64_on_both_paths() -> None:
    rng = np.random.default_rng(10)
    forces = np.concatenate([np.exp(rng.uniform(-9.0, 7.0, 20000)), [0.0, 1e-6, 1e-3, 1.0]]).astype(np.float32)
    points = np.zeros((len(forces), 3), dtype=np.float32)
    points[:, 2] = forces
    batch = _log_force(points)
    single = np.array([one_log_force(f) for f in forces.tolist()])
    assert batch.dtype == np.float64
    np.testing.assert_array_max_ulp(single, batch, maxulp=1)
    assert (single == batch).mean() > 0.99
    floor = float(np.float32(1e-3))
    assert single[-4] == single[-3] == math.log(floor)  # clipped at 1 mN (float32)
    want = np.log(np.maximum(forces.astype(np.float64), floor))
    np.testing.assert_array_equal(batch, want)


def test_whole_codes_read_the_packed_conductances() -> None:
    check = one_press_check(SCENE).prepare().one_frame
    codes = np.random.default_rng(11).integers(0, fsr.Readout(SCENE.sensor.readout).full_scale, (200, 6))
    for row in codes.astype(float).tolist():
        assert check.measured_of_whole(row) == check.measured(row)


def test_a_calibrated_films_stream_takes_the_checked_path() -> None:
    film = dataclasses.replace(SCENE.sensor.film, gains=(1.05, 0.95, 1.02, 0.97, 1.04, 0.96), gain_spread=0.0)
    scene = dataclasses.replace(SCENE, sensor=dataclasses.replace(SCENE.sensor, film=film))
    est = TriangulationEstimator(scene).prepare()
    assert est.one_frame_run() is None and FrameStream(est)._run_one is None
    frames = _frames(40, 406)
    single = np.concatenate([est.predict(frames[i : i + 1]) for i in range(len(frames))])
    np.testing.assert_allclose(single, est.predict(frames), rtol=1e-6, atol=1e-5)
