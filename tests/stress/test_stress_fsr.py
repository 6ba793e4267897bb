"""Property-based stress tests of the FSR film: forward model, simulator, the classical and shipped
learned estimators and bad input, over the documented ranges and beyond them (zero and 1e3 N
loads, tiny tips, contacts on the film's border and off it, batch sizes 0, 1 and large).
Invariants, not magic numbers. `make stress` runs many more examples (TACTILE_STRESS=1)."""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from synth.errors import InputError
from synth.scene import Scene, load_scene, parse_scene
from synth.sensors import fsr
from tactile_learn.estimators.base import Estimator
from tactile_learn.estimators.classical.triangulation import (
    FittedTriangulationEstimator,
    TriangulationEstimator,
    triangulate,
)
from tactile_learn.runtime import OnnxEstimator
from tests.paths import REPO_ROOT

pytestmark = pytest.mark.stress

ROOT = REPO_ROOT
ONNX_MODELS = sorted(p.name for p in (ROOT / "models").glob("fsr*.onnx"))
#: a contact rotated by 120 degrees about the film's centre: sensor i reads what sensor PERM[i]
#: read before (S0 -> S1 -> S2 -> S0 at the corners, S3 -> S5 -> S4 -> S3 at the midpoints)
PERM = np.array([1, 2, 0, 5, 3, 4])
ROT = np.array([[-0.5, -math.sqrt(3.0) / 2], [math.sqrt(3.0) / 2, -0.5]])
#: the three mirror symmetries of the layout, as sensor permutations
MIRRORS = (np.array([0, 2, 1, 4, 3, 5]), np.array([2, 1, 0, 5, 4, 3]), np.array([1, 0, 2, 3, 5, 4]))


def fewer(n: int) -> Callable[[Any], Any]:
    """At most ``n`` examples in the fast profile (a slow test); the stress profile's full count."""
    if os.environ.get("TACTILE_STRESS"):
        return settings()
    return settings(max_examples=min(n, settings.default.max_examples))


@cache
def scene() -> Scene:
    return load_scene("fsr6")


@cache
def clean() -> fsr.FsrSimulator:
    return fsr.FsrSimulator(scene().sensor, ("readings",), noise=False)


def full_scale() -> int:
    return fsr.Readout(scene().sensor.readout).full_scale


def log_uniform(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(math.log(lo), math.log(hi)).map(lambda v: min(max(math.exp(v), lo), hi))


# ---- forward model ------------------------------------------------------------------------------

HALF = 40.0  # the fsr6 film's half side (mm)
coordinates = st.one_of(
    st.sampled_from([0.0, HALF - 1.0, HALF, -HALF, HALF + 1e-9, -HALF - 5.0, 200.0, -1e4]),  # border, off it
    st.floats(-HALF, HALF),
    st.floats(-300.0, 300.0),
)
forces = st.one_of(
    st.sampled_from([0.0, 1e-300, 1e-12, 0.15, 1e3]),  # none, near-zero, the break force, 1e3 N
    st.floats(0.0, 1e-3),
    st.floats(0.0, 20.0),
    st.floats(0.0, 1e3),
)
tips = st.one_of(st.sampled_from([1e-9, 0.1, 100.0]), log_uniform(1e-9, 100.0))  # down to a needle
gains = st.one_of(
    st.sampled_from([1.0, 0.05, 20.0]),
    st.lists(st.floats(0.05, 20.0), min_size=6, max_size=6).map(np.array),
)


@given(coordinates, coordinates, st.lists(forces, min_size=1, max_size=12), tips, gains, st.booleans())
def test_readings_are_finite_within_the_adc_and_monotone_in_force(
    x: float, y: float, force: list[float], tip: float, gain: Any, quantise: bool
) -> None:
    f = np.sort(np.array([0.0, *force]))
    xy = np.broadcast_to([x, y], (len(f), 2))
    codes = clean().forward(xy, f, tip, gain, quantise=quantise)
    assert codes.shape == (len(f), 6) and np.isfinite(codes).all()
    assert (codes >= 0).all() and (codes <= full_scale()).all()
    assert (np.diff(codes, axis=0) >= 0).all()  # more force never lowers a reading
    leak = clean().forward(np.zeros((1, 2)), np.zeros(1), tip, gain, quantise=quantise)
    assert np.array_equal(codes[0], leak[0])  # no force: the leak's reading wherever the contact is


@given(coordinates, coordinates, forces, tips)
def test_disc_loads_are_non_negative_and_never_exceed_the_applied_force(
    x: float, y: float, force: float, tip: float
) -> None:
    loads = fsr.sensor_loads(scene().sensor, np.array([[x, y]]), np.array([force]), np.array([tip]))
    assert loads.shape == (1, 6) and np.isfinite(loads).all() and (loads >= 0).all()
    assert loads.sum() <= force * (1 + 1e-9)
    if force == 0.0:
        assert not loads.any()


@given(st.sampled_from([0, 1, 2, 1000]), st.integers(0, 2**32 - 1))
def test_forward_batches_of_any_size_answer_row_by_row(batch: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-60.0, 60.0, (batch, 2))
    force = np.exp(rng.uniform(math.log(1e-4), math.log(1e3), batch))
    tip = np.exp(rng.uniform(math.log(1e-3), math.log(100.0), batch))
    codes = clean().forward(xy, force, tip)
    assert codes.shape == (batch, 6)
    for i in rng.choice(batch, size=min(batch, 5), replace=False) if batch else []:
        assert np.array_equal(clean().forward(xy[i : i + 1], force[i : i + 1], tip[i]), codes[i : i + 1])
    # float32 contacts, strided and read-only arrays: the same readings as their float64 copies
    xy32 = xy.astype(np.float32)
    frozen = np.repeat(xy32, 2, axis=0)[::2]
    frozen.setflags(write=False)
    ref = clean().forward(xy32.astype(np.float64), force.astype(np.float32).astype(np.float64), tip)
    assert np.array_equal(clean().forward(frozen, force.astype(np.float32), tip), ref)


@given(coordinates, coordinates, forces, tips)
def test_a_contact_rotated_by_120_degrees_permutes_the_readings(x: float, y: float, force: float, tip: float) -> None:
    xy = np.array([[x, y]])
    a = clean().forward(xy, np.array([force]), tip, quantise=False)
    b = clean().forward(xy @ ROT.T, np.array([force]), tip, quantise=False)
    assert np.allclose(b[:, PERM], a, rtol=0, atol=1e-6)


@st.composite
def fsr_scenes(draw: st.DrawFn) -> Scene:
    """Stimuli and films over (and at the edges of) their documented ranges."""
    data = load_scene("fsr6").to_dict()
    cfg = data["fsr"]
    lo = min(draw(log_uniform(0.0011, 100.0)), 100.0)
    cfg["stimulus"].update(
        force_range_n=[lo, draw(st.floats(lo, 100.0))],
        tip_radii_mm=draw(st.lists(log_uniform(0.1001, 100.0), min_size=1, max_size=3)),
        no_contact_fraction=draw(st.floats(0.0, 1.0)),
        inside_fraction=draw(st.floats(0.0, 1.0)),
        edge_margin_mm=draw(st.sampled_from([0.0, 1.0, 20.0])),
    )
    cfg["film"].update(
        gain_spread=draw(st.floats(0.0, 0.5)),
        repeatability=draw(st.floats(0.0, 0.5)),
        distribution=draw(st.sampled_from(["uniform", "normal"])),
        frames_per_film=draw(st.sampled_from([1, 64])),
    )
    cfg["readout"].update(noise_lsb=draw(st.sampled_from([0.0, 0.7, 100.0])), adc_bits=draw(st.integers(4, 10)))
    data["noise"] = draw(st.booleans())
    data["outputs"] = ["readings", "truth", "sensor_force", "latent"]
    return parse_scene(data)


@fewer(20)
@given(fsr_scenes(), st.integers(0, 2**32 - 1), st.sampled_from([0, 1, 7, 500]))
def test_simulator_outputs_are_finite_and_consistent_for_any_stimulus(scene_: Scene, seed: int, batch: int) -> None:
    out = fsr.make_simulator(scene_).simulate(batch, np.random.default_rng(seed))
    for key, value in out.items():
        assert len(value) == batch, key
        if value.dtype.kind == "f":
            assert np.isfinite(value).all(), key
    full = fsr.Readout(scene_.sensor.readout).full_scale
    assert out["readings"].dtype == np.float32
    assert (out["readings"] >= 0).all() and (out["readings"] <= full).all()
    contact = out["latent_contact"]
    assert np.array_equal(out["force_n"] > 0, contact)
    assert not out["sensor_force_n"][~contact].any() and (out["sensor_force_n"] >= 0).all()
    assert (out["sensor_force_n"].sum(axis=1) <= out["force_n"] * (1 + 1e-5) + 1e-12).all()


# ---- estimators ---------------------------------------------------------------------------------

CLASSICAL = ["triangulation", "triangulation_fit"]
METHODS = [*CLASSICAL, *(f"onnx:{name}" for name in ONNX_MODELS)]


@cache
def estimator(method: str) -> Estimator:
    if method.startswith("onnx:"):
        return OnnxEstimator(ROOT / "models" / method.removeprefix("onnx:")).prepare()
    cls = {"triangulation": TriangulationEstimator, "triangulation_fit": FittedTriangulationEstimator}[method]
    return cls(scene()).fit()


def loads_of(readings: np.ndarray) -> np.ndarray:
    """Disc loads the classical estimators read from codes (nominal film)."""
    return clean().loads_from_readings(np.asarray(readings, dtype=np.float32))


codes = st.one_of(
    st.sampled_from([0.0, 1e-6, 1.0, 1022.0, 1022.999]),  # zero, near-zero, just below saturation
    st.floats(0.0, 1022.999),
    st.integers(0, 1022).map(float),
)


def readings(batch: st.SearchStrategy[int] | None = None) -> st.SearchStrategy[np.ndarray]:
    """Valid code arrays, (B, 6), float32 or float64; B from ``batch`` (default 0, 1, 2 or 5)."""
    return (st.sampled_from([0, 1, 2, 5]) if batch is None else batch).flatmap(
        lambda b: hnp.arrays(
            st.sampled_from([np.float32, np.float64]), (b, 6), elements=codes.map(lambda v: float(np.float32(v)))
        )
    )


def check_estimate(method: str, x: np.ndarray, out: np.ndarray) -> None:
    """The fsr prediction format, with the classical estimators' flags (see triangulation's docs)."""
    assert out.shape == (len(x), 6) and out.dtype == np.float32 and np.isfinite(out).all()
    assert ((out[:, 3:] >= 0) & (out[:, 3:] <= 1)).all()
    if method not in CLASSICAL:
        return
    loads = loads_of(x)
    contact = loads.max(axis=1, initial=0.0) >= scene().sensor.element.break_force_n
    assert np.array_equal(out[:, 3] == 1, contact) and np.isin(out[:, 3], (0.0, 1.0)).all()
    assert np.isin(out[:, 4], (0.0, 0.5, 1.0)).all() and (out[:, 2] >= 0).all()
    assert not out[~contact].any()  # no contact: every column 0


@pytest.mark.parametrize("method", METHODS)
@given(x=readings())
def test_any_valid_reading_gives_a_defined_estimate(method: str, x: np.ndarray) -> None:
    check_estimate(method, x, estimator(method).predict(x))


@pytest.mark.parametrize("method", METHODS)
@given(x=readings(st.integers(1, 4)))
def test_dtype_layout_and_read_only_inputs_give_the_same_answer(method: str, x: np.ndarray) -> None:
    est = estimator(method)
    x32 = x.astype(np.float32)
    ref = est.predict(x32)
    frozen = x32.copy()
    frozen.setflags(write=False)
    variants = {
        "float64": x32.astype(np.float64),
        "big-endian": x32.astype(">f8"),
        "fortran": np.asfortranarray(x32),
        "strided": np.repeat(x32, 2, axis=1)[:, ::2],
        "column view": np.concatenate([x32, x32], axis=1)[:, :6],
        "read-only": frozen,
        "list": x32.tolist(),
    }
    if np.array_equal(x32, np.round(x32)):
        variants["int16 codes"] = x32.astype(np.int16)
    for name, variant in variants.items():
        assert np.array_equal(est.predict(variant), ref), name


@pytest.mark.parametrize("method", METHODS)
def test_large_batches_answer_row_by_row(method: str) -> None:
    rng = np.random.default_rng(5)
    n = 20000
    xy = rng.uniform(-HALF, HALF, (n, 2))
    force = np.where(rng.random(n) < 0.1, 0.0, np.exp(rng.uniform(math.log(0.01), math.log(100.0), n)))
    x = clean().forward(xy, force, rng.choice([2.0, 4.0, 8.0], n), rng=rng).astype(np.float32)
    x = np.minimum(x, full_scale() - 1)
    est = estimator(method)
    out = est.predict(x)
    check_estimate(method, x, out)
    tol = 1e-5 if method.startswith("onnx:") else 0.0
    assert np.allclose(est.predict(x[::-1])[::-1], out, rtol=0, atol=tol)
    for i in (0, 1, n // 2, n - 1):
        assert np.allclose(est.predict(x[i : i + 1]), out[i : i + 1], rtol=0, atol=tol)
    assert est.predict(x[:0]).shape == (0, 6)


def code_for_load(load: float) -> float:
    """The nominal film's (unquantised) code for a disc load (N)."""
    law = clean().law
    return float(clean().readout.codes(law.conductance_us(np.array(load)), quantise=False))


@pytest.mark.parametrize("method", CLASSICAL)
@given(
    above=st.lists(st.integers(0, 5), min_size=1, max_size=2, unique=True),
    strong=st.lists(st.floats(1.05, 400.0), min_size=2, max_size=2),
    weak=st.lists(st.floats(0.0, 0.95), min_size=6, max_size=6),
)
def test_one_or_two_sensors_above_the_break_give_flagged_estimates(
    method: str, above: list[int], strong: list[float], weak: list[float]
) -> None:
    """Degenerate frames: with a single sensor above the break force (or two that share no
    triangle) the contact is put on a sensor above it and inside/outside is undecided (0.5); with
    two of one triangle, the closed form runs with the third load at its documented fallback and
    the frame is located and flagged inside or not (1 or 0)."""
    brk = scene().sensor.element.break_force_n
    loads = np.array(weak) * brk
    loads[above] = np.array(strong[: len(above)]) * brk
    x = np.array([[min(code_for_load(v), full_scale() - 1e-3) for v in loads]], dtype=np.float32)
    valid = loads_of(x)[0] >= brk
    assume(valid.sum() == len(above))  # the code's rounding kept every sensor on its side of the break
    out = estimator(method).predict(x)
    check_estimate(method, x, out)
    assert out[0, 3] == 1 and out[0, 2] > 0
    if any(set(above) <= set(tri) for tri in fsr.TRIANGLES) and len(above) == 2:
        assert out[0, 4] in (0.0, 1.0)
    else:
        positions = fsr.sensor_positions(scene().sensor.layout)[above]
        assert np.abs(positions - out[0, :2]).max(axis=1).min() <= 1e-4 and out[0, 4] == 0.5


@pytest.mark.parametrize("method", METHODS)
def test_all_zero_and_baseline_frames_are_no_contact(method: str) -> None:
    x = np.zeros((4, 6), dtype=np.float32)
    x[1:] = clean().forward(np.zeros((3, 2)), np.zeros(3), 4.0)  # the leak's codes
    out = estimator(method).predict(x)
    check_estimate(method, x, out)
    if method in CLASSICAL:
        assert not out.any()
    else:
        assert (out[:, 3] < 0.5).all()


@pytest.mark.parametrize("method", CLASSICAL)
# Hypothesis seeds its floats with constants mined from every local module imported so far, so how
# many of these draws are saturated or mirror-symmetric (and filtered) depends on what the suite
# imported before: a filtering health check here fails or passes with the test order, not the code
@settings(suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.too_slow])
@given(
    st.one_of(st.floats(0.0, 2 * HALF), st.floats(0.0, 300.0)),
    st.integers(0, 5),
    st.floats(0.5, 59.5),
    st.one_of(st.floats(0.16, 20.0), st.floats(0.16, 1e3)),
    st.sampled_from([2.0, 4.0, 8.0]),
)
def test_estimates_rotate_with_the_contact(
    method: str, radius: float, sector: int, angle: float, force: float, tip: float
) -> None:
    """Consistency with the film's symmetry: readings of a contact rotated by 120 degrees give the
    estimate rotated by 120 degrees. (Contacts off the mirror axes, at 30 + 60 k degrees: a frame that
    is mirror-symmetric ties two triangles, whose order then decides; such frames are skipped.)"""
    theta = math.radians(30.0 + 60.0 * sector + angle)
    x, y = radius * math.cos(theta), radius * math.sin(theta)
    a = clean().forward(np.array([[x, y]]), np.array([force]), tip).astype(np.float32)
    assume(a.max() < full_scale())
    assume(not any(np.array_equal(a[:, m], a) for m in MIRRORS))
    b = a[:, np.argsort(PERM)]  # the rotated contact's readings (the forward model's symmetry, tested above)
    est = estimator(method)
    pa, pb = est.predict(a), est.predict(b)
    assert np.allclose(pb[:, :2], pa[:, :2] @ ROT.T, rtol=0, atol=1e-3)
    assert np.allclose(pb[:, 2:5], pa[:, 2:5], rtol=1e-5, atol=1e-6)
    # (column 5, the one-press check, refines the estimate by a few steps that are not exactly
    # rotation-equivariant: its flag is tested in test_fsr_flagging.py, not here)


@pytest.mark.parametrize("method", CLASSICAL)
@given(st.integers(0, 3), st.lists(st.floats(0.02, 1.0), min_size=3, max_size=3), log_uniform(1.5, 1e3))
def test_the_closed_form_inverts_its_own_load_model(
    method: str, triangle: int, weights: list[float], strength: float
) -> None:
    """Consistency with the forward model the closed form assumes: disc loads that follow its own
    load model exactly (all six above the break force) give back the contact's position and force."""
    est = estimator(method)
    assert isinstance(est, TriangulationEstimator)
    model = est.model_
    corners = fsr.triangle_vertices(scene().sensor.layout)[triangle]
    xy = (np.array(weights) / sum(weights)) @ corners
    r = np.linalg.norm(fsr.sensor_positions(scene().sensor.layout) - xy, axis=1)
    brk = scene().sensor.element.break_force_n
    force = strength * brk / float(model.load(r, 1.0).min())  # every disc at 1.5x the break or more
    loads = model.load(r, force)[None, :]
    out, n_valid = triangulate(loads, scene().sensor, model, brk)
    assert n_valid[0] == 3 and out[0, 3] == 1
    assert np.allclose(out[0, :2], xy, rtol=0, atol=1e-6 * max(1.0, float(np.abs(xy).max())))
    assert out[0, 2] == pytest.approx(model.force_scale * force, rel=1e-6)


# ---- bad input ----------------------------------------------------------------------------------

BAD_INPUTS: list[tuple[str, Any, str]] = [
    ("nan", np.full((2, 6), np.nan), "NaN or inf"),
    ("inf", np.full((1, 6), np.inf), "NaN or inf"),
    ("negative", np.full((1, 6), -1.0), "negative"),
    ("saturated", np.full((1, 6), 1023.0), "saturated"),
    ("far above full scale", np.full((1, 6), 1e30), "saturated"),
    ("too many sensors", np.zeros((1, 7)), r"expected shape \('B', 6\)"),
    ("too few sensors", np.zeros((3, 5)), r"expected shape \('B', 6\)"),
    ("no batch axis", np.zeros(6), "batch axis"),
    ("3-d", np.zeros((1, 1, 6)), "expected shape"),
    ("scalar", 0.0, "expected shape"),
    ("strings", np.array([["1"] * 6]), "expected numbers"),
    ("objects", np.array([[None] * 6], dtype=object), "expected numbers"),
    ("complex", np.zeros((1, 6), complex), "real numbers"),
    ("ragged", [[0.0] * 6, [0.0] * 5], "cannot be read|expected numbers"),
    ("dict", {"readings": [0.0] * 6}, "expected numbers|expected shape"),
]


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize(("case", "bad", "message"), BAD_INPUTS, ids=[b[0] for b in BAD_INPUTS])
def test_bad_input_is_refused_with_a_message_naming_it(method: str, case: str, bad: Any, message: str) -> None:
    with pytest.raises(InputError, match=message):
        estimator(method).predict(bad)


@pytest.mark.parametrize("method", METHODS)
@given(
    x=readings(st.integers(1, 5)),
    data=st.data(),
    bad=st.sampled_from([math.nan, math.inf, -math.inf, -1e-3, -1e30, 1023.0, 1e9]),
)
def test_one_bad_value_in_a_valid_batch_names_its_frame(
    method: str, x: np.ndarray, data: st.DataObject, bad: float
) -> None:
    x = x.astype(np.float64)
    row = data.draw(st.integers(0, len(x) - 1))
    x[row, data.draw(st.integers(0, 5))] = bad
    with pytest.raises(InputError, match=f"frame {row}"):
        estimator(method).predict(x)
