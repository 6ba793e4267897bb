"""Triangulation's single frames by code: the code -> load table holds exactly the whole codes the
input check passes, with the batch inverse's loads; the stream's runner and ``predict`` give the
batch path's answers."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from synth.errors import InputError
from synth.scene import load_scene
from synth.sensors import fsr
from tactile_learn.estimators.classical.triangulation import FittedTriangulationEstimator, TriangulationEstimator
from tactile_learn.frame_stream import FrameStream

SCENE = load_scene("fsr6")


def test_table_holds_the_whole_codes_the_check_passes() -> None:
    est = FittedTriangulationEstimator(SCENE).prepare()
    table = est.one_frame_.load_of_code
    full_scale = fsr.Readout(SCENE.sensor.readout).full_scale
    codes = np.arange(-3.0, full_scale + 4.0)
    passes = []
    for code in codes:
        try:
            est.input_check_(np.full((1, fsr.N_SENSORS), code, dtype=np.float32))
            passes.append(float(code))
        except InputError:
            pass
    assert sorted(table) == passes and len(passes) == full_scale  # 0 .. full scale - 1
    inverse = est.simulator_.loads_from_readings(np.array(passes, dtype=np.float64))
    assert [table[c] for c in passes] == inverse.tolist()


def test_a_calibrated_film_has_no_table() -> None:
    film = dataclasses.replace(SCENE.sensor.film, gains=(1.05, 0.95, 1.0, 1.1, 0.9, 1.02))
    scene = dataclasses.replace(SCENE, sensor=dataclasses.replace(SCENE.sensor, film=film))
    assert FittedTriangulationEstimator(scene).prepare().one_frame_.load_of_code == {}


@pytest.mark.parametrize("cls", [TriangulationEstimator, FittedTriangulationEstimator])
def test_runner_stream_and_predict_give_the_batch_answers(cls: type[TriangulationEstimator]) -> None:
    rng = np.random.default_rng(77)
    frames = np.ascontiguousarray(fsr.make_simulator(SCENE).simulate(400, rng)["readings"], dtype=np.float32)
    frames[::9, 1] += 0.25  # codes between two whole codes: the batch inverse
    est = cls(SCENE).prepare()
    batch = est.predict(frames)
    run = est.frame_runner()
    stream = FrameStream(est)
    by_runner = np.concatenate([run(frames[i : i + 1]) for i in range(len(frames))])
    by_predict = np.concatenate([est.predict(frames[i : i + 1]) for i in range(len(frames))])
    streamed = np.concatenate([stream.predict(frames[i : i + 1]) for i in range(len(frames))])
    assert 0.3 < (batch[:, 3] > 0).mean() < 0.9  # contacts and frames without
    np.testing.assert_allclose(by_predict, batch, rtol=1e-6, atol=1e-5)
    np.testing.assert_array_equal(by_predict[:, 3:], batch[:, 3:])
    np.testing.assert_array_equal(by_runner, by_predict)
    np.testing.assert_array_equal(streamed, by_predict)


def test_the_checks_code_lookup_is_the_readout_inverse() -> None:
    check = FittedTriangulationEstimator(SCENE).prepare().check_.one_frame
    readout = check.readout
    codes = [0.0, 1.0, 17.0, 512.0, 1022.0, 1023.0]
    assert check.measured(codes) == readout.conductance_us(np.array(codes)).tolist()
    fractional = [0.5, 1.0, 17.25, 512.0, 1022.0, 3.0]
    assert check.measured(fractional) == [float(g) for g in readout.conductance_us(np.array(fractional))]
    assert len(check.conductance_of_code) == 2**SCENE.sensor.readout.adc_bits
