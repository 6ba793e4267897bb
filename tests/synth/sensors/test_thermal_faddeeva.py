"""The numpy complex erfcx (synth.sensors.thermal.faddeeva) against scipy.special.erfcx."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import special

from synth.scene import load_scene
from synth.sensors.thermal import make_simulator
from synth.sensors.thermal.faddeeva import erfcx_minus_one_real, erfcx_right
from synth.sensors.thermal.physics import ContactModel


def _relative_error(y: np.ndarray) -> np.ndarray:
    ref = special.erfcx(y)
    return np.abs(erfcx_right(y) - ref) / np.abs(ref)


def test_erfcx_right_is_scipys_over_the_right_half_plane() -> None:
    """|y| from 0 to 1e4 (log-spaced), arguments from -90 to +90 degrees, both axes included:
    scipy's own error there is up to ~3e-14 (near the imaginary axis), the rational series' ~1e-15."""
    size = np.concatenate([[0.0], np.geomspace(1e-6, 1e4, 400)])
    angle = np.radians(np.linspace(-90.0, 90.0, 181))
    y = size[:, None] * np.exp(1j * angle)[None, :]
    y.real[:, [0, -1]] = 0.0  # the imaginary axis exactly (cos(90 deg) is not 0 in floating point)
    err = _relative_error(y)
    assert err.max() < 5e-14
    assert np.median(err) < 1e-15


def test_erfcx_right_random_arguments_and_real_axis() -> None:
    rng = np.random.default_rng(4)
    y = rng.uniform(0.0, 12.0, 20_000) + 1j * rng.uniform(-12.0, 12.0, 20_000)
    assert _relative_error(y).max() < 5e-14
    x = np.geomspace(1e-8, 1e5, 500).astype(np.complex128)  # real arguments, a complex dtype
    assert _relative_error(x).max() < 5e-14


def test_erfcx_right_keeps_shape_and_hands_the_rest_to_scipy() -> None:
    y = np.array([[1.0 - 2.0j, -1.0 + 0.5j], [np.nan + 0.0j, complex(np.inf, 0.0)], [1e120 + 0j, -3.0 - 3.0j]])
    got = erfcx_right(y)
    assert got.shape == y.shape
    ref = special.erfcx(y)
    # the left half-plane (where the rational form does not hold), NaN, inf and huge |y|: scipy's values
    np.testing.assert_array_equal(got.ravel()[1:], ref.ravel()[1:])
    assert abs(got[0, 0] - ref[0, 0]) < 5e-14 * abs(ref[0, 0])
    assert erfcx_right(np.zeros(0, dtype=np.complex128)).shape == (0,)


def test_erfcx_minus_one_real_is_the_weighted_real_part() -> None:
    """Rows of several chunks (and a left half-plane value, which goes to scipy), weights per row."""
    rng = np.random.default_rng(6)
    rows, n = 700, 130
    y = rng.uniform(0.0, 10.0, (rows, n)) * np.exp(-1j * rng.uniform(0.0, np.pi / 2, (rows, n)))
    y[3, 5] = -2.0 + 1.0j
    weight = rng.normal(size=rows) + 1j * rng.normal(size=rows)
    got = erfcx_minus_one_real(y, weight)
    ref = (weight[:, None] * (special.erfcx(y) - 1.0)).real
    assert got.shape == (rows, n) and got.dtype == np.float64
    scale = np.abs(weight)[:, None] * (np.abs(special.erfcx(y)) + 1.0)
    assert (np.abs(got - ref) / scale).max() < 5e-14
    with pytest.raises(ValueError, match="weight"):
        erfcx_minus_one_real(y, weight[:-1])


@pytest.mark.parametrize("name", ["thermal", "thermal_wns"])
def test_the_simulators_complex_arguments_lie_in_the_verified_region(name: str) -> None:
    """Every root of the scenes' contacts has Re p < 0, so y = -p sqrt(t) has Re y >= 0, and the
    complex roots' |y| stays far inside the range checked above over the whole record."""
    scene = load_scene(name).with_noise(False)
    sim = make_simulator(scene)
    d = sim.draw(400, np.random.default_rng(8)).params
    model = ContactModel.of_touched(d)
    roots, _ = model.poles
    assert (roots.real < 0).all()
    pairs = roots[roots.imag != 0]  # the real roots take the real erfcx
    assert len(pairs)
    y = -pairs[:, None] * np.sqrt(np.linspace(0.0, scene.sensor.readout.duration_s, 50))
    assert np.abs(y).max() < 1e3
    assert _relative_error(y[np.abs(y) > 0]).max() < 5e-14
