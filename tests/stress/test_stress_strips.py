"""Property-based stress tests of the strip array: forward model, stimuli and estimators, over
the documented ranges and beyond them. Invariants, not magic numbers. `make stress` runs many
more examples (TACTILE_STRESS=1)."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from synth.errors import InputError
from synth.scene import Scene, load_scene, parse_scene
from synth.sensors.strips import StripSensor, StripSimulator
from tactile_learn.estimators.classical.intersection import IntersectionEstimator
from tactile_learn.estimators.classical.projection import ProjectionEstimator

pytestmark = pytest.mark.stress


@cache
def scene5() -> Scene:
    return load_scene("strips5")


@cache
def sensor5() -> StripSensor:
    return StripSensor(scene5().sensor)


pressures = st.one_of(
    st.just(0.0),
    st.floats(0, 1e-6),
    st.floats(0, 1e3),
    st.floats(1e3, 1e7),  # far beyond any documented stimulus: must stay finite and saturate
)


@st.composite
def fields(draw: st.DrawFn, max_batch: int = 3) -> np.ndarray:
    batch = draw(st.integers(0, max_batch))
    shape = (batch, *sensor5().field_shape)
    dtype = draw(st.sampled_from([np.float32, np.float64]))
    sparse = draw(st.booleans())
    values = draw(hnp.arrays(dtype, shape, elements=pressures))
    if sparse and values.size:
        mask = draw(hnp.arrays(np.bool_, shape))
        values = np.where(mask, values, 0)
    return values


@given(fields())
def test_forward_is_finite_bounded_and_non_negative(field: np.ndarray) -> None:
    sensor = sensor5()
    out = sensor.forward(field)
    readings = out["readings"]
    assert readings.shape == (len(field), 10) and readings.dtype == np.float32
    assert np.isfinite(readings).all() and np.isfinite(out["pressure"]).all()
    assert (readings >= scene5().sensor.readout.offset_v - 1e-6).all()
    assert (readings <= scene5().sensor.readout.full_scale_v).all()
    assert (out["pressure"] >= 0).all()


@given(fields(max_batch=2), st.floats(0, 1e4), st.integers(0, 19), st.integers(0, 19))
def test_more_pressure_never_lowers_a_reading(field: np.ndarray, extra: float, y: int, x: int) -> None:
    assume(len(field) > 0)
    more = field.astype(np.float64).copy()
    more[:, y, x] += extra
    a = sensor5().forward(field)["readings"]
    b = sensor5().forward(more)["readings"]
    assert (b >= a - 2e-6).all()


@given(fields(max_batch=2))
def test_float32_field_matches_float64(field: np.ndarray) -> None:
    a = sensor5().forward(field.astype(np.float32))["readings"]
    b = sensor5().forward(field.astype(np.float64))["readings"]
    assert np.allclose(a, b, atol=1e-5)  # stated tolerance: 10 uV, a hundredth of an ADC step


@given(fields(max_batch=2))
def test_forward_accepts_read_only_and_non_contiguous_fields(field: np.ndarray) -> None:
    ref = sensor5().forward(field)["readings"]
    frozen = field.copy()
    frozen.setflags(write=False)
    assert np.array_equal(sensor5().forward(frozen)["readings"], ref)
    strided = np.repeat(field, 2, axis=0)[::2]
    assert np.array_equal(sensor5().forward(strided)["readings"], ref)


@st.composite
def stimulus_scenes(draw: st.DrawFn) -> Scene:
    kind = draw(st.sampled_from(["sphere", "punch", "block", "edge"]))
    lo_f = draw(st.floats(0.0, 50.0))
    hi_f = draw(st.floats(lo_f, 200.0))
    lo_r = draw(st.floats(0.01, 20.0))
    hi_r = draw(st.floats(lo_r, 40.0))
    lo_l = draw(st.floats(0.01, 10.0))
    spec = {
        "kind": kind,
        "force_n": [lo_f, hi_f],
        "radius_mm": [lo_r, hi_r],
        "width_mm": [max(lo_r / 4, 0.01), max(hi_r / 4, 0.01)],
        "length_mm": [lo_l, lo_l + draw(st.floats(0, 30))],
        "angle_deg": [0.0, draw(st.floats(0, 360))],
    }
    data = load_scene("strips5").to_dict()
    data["strips"]["stimuli"] = {
        "count": [0, draw(st.integers(0, 4))],
        "margin_mm": draw(st.floats(-15.0, 10.0)),
        "empty_fraction": draw(st.floats(0, 1)),
        "kinds": [spec],
    }
    data["noise"] = draw(st.booleans())
    data["outputs"] = ["readings", "pressure", "field", "latent"]
    return parse_scene(data)


@given(stimulus_scenes(), st.integers(0, 2**32 - 1), st.sampled_from([0, 1, 7, 64]))
def test_simulator_outputs_are_finite_for_any_stimulus(scene: Scene, seed: int, batch: int) -> None:
    out = StripSimulator(scene).simulate(batch, np.random.default_rng(seed))
    for key, value in out.items():
        assert len(value) == batch, key
        if value.dtype.kind == "f":
            assert np.isfinite(value).all(), key
    assert (out["pressure"] >= 0).all() and (out["field"] >= 0).all()
    readout = scene.sensor.readout
    assert (out["readings"] >= 0).all() and (out["readings"] <= readout.full_scale_v).all()
    # load inside the array's lattice never exceeds the contacts' total force
    h = scene.sensor.geometry.pitch_mm / scene.sensor.geometry.samples_per_pitch
    carried = out["field"].astype(np.float64).sum(axis=(1, 2)) * h * h / 1000
    assert (carried <= out["latent_force_n"].sum(axis=1) * (1 + 1e-4) + 1e-6).all()


@cache
def estimators() -> tuple[IntersectionEstimator, ProjectionEstimator]:
    return IntersectionEstimator(scene5()).prepare(), ProjectionEstimator(scene5()).prepare()


@given(st.integers(0, 9), st.floats(0, 0.999))
def test_estimators_give_finite_non_negative_maps_for_any_valid_reading(batch: int, level: float) -> None:
    readout = scene5().sensor.readout
    rng = np.random.default_rng(batch)
    readings = rng.uniform(0, readout.full_scale_v * level, size=(batch, 10)).astype(np.float32)
    for est in estimators():
        maps = est.predict(readings)
        assert maps.shape == (batch, 5, 5) and np.isfinite(maps).all() and (maps >= 0).all()


def test_baseline_frames_give_all_zero_maps_and_saturation_is_refused() -> None:
    readout = scene5().sensor.readout
    baseline = np.full((3, 10), readout.offset_v, np.float32)
    for est in estimators():
        assert not est.predict(baseline).any()
        saturated = baseline.copy()
        saturated[1, 4] = readout.full_scale_v
        with pytest.raises(InputError, match="saturated"):
            est.predict(saturated)


def projection_misfit_ratio(force: float, x: float, y: float) -> float:
    """Misfit of the projection estimate's own loads to the measured ones, relative to the
    intersection estimate's, for a noise-free 2 mm disc contact; asserts it never grows."""
    sensor = sensor5()
    h = sensor.field_pitch_mm
    ny, nx = sensor.field_shape
    yy, xx = np.meshgrid((np.arange(ny) + 0.5) * h, (np.arange(nx) + 0.5) * h, indexing="ij")
    a = 2.0
    field = np.where((xx - x) ** 2 + (yy - y) ** 2 < a * a, force * 1000 / (np.pi * a * a), 0.0)[None]
    readings = sensor.forward(field)["readings"]
    projection = estimators()[1]
    maps = projection.predict(readings)
    model, _ = projection._loads(maps.reshape(1, -1).astype(np.float32))
    loads = sensor.invert_readings(readings)[0]
    misfit = np.abs(model[0] - loads)
    start = estimators()[0].predict(readings).reshape(1, -1).astype(np.float32)
    intersection_misfit = np.abs(projection._loads(start)[0][0] - loads)
    # the refinement never moves away from the readings (it cannot reach them exactly: a map of
    # cell-mean pressures cannot represent a contact much smaller than a cell)
    assert misfit.sum() <= intersection_misfit.sum() + 1e-6
    return float(misfit.sum() / max(intersection_misfit.sum(), 1e-12))


@given(st.floats(1.0, 8.0), st.floats(3.0, 22.0), st.floats(3.0, 22.0))
def test_projection_moves_towards_noise_free_readings(force: float, x: float, y: float) -> None:
    """Consistency with the forward model: the refinement's own readings are closer to the input's."""
    projection_misfit_ratio(force, x, y)


def test_projection_removes_a_good_share_of_the_misfit_on_average() -> None:
    ratios = [
        projection_misfit_ratio(force, x, y)
        for force in (1.0, 3.0, 6.0)
        for x in (4.0, 9.0, 16.5)
        for y in (5.0, 11.0, 20.0)
    ]
    assert np.mean(ratios) < 0.8 and max(ratios) < 0.95
