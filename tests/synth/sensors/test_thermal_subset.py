"""Thermal touches of which only some pixels are read: the same pixel curves, a fraction of the work."""

from __future__ import annotations

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.errors import ConfigError
from synth.scene import load_scene
from synth.sensors.thermal import TouchGenerator, make_simulator
from synth.sensors.thermal.subset import take_pixels

N = 24


@pytest.mark.parametrize("name", ["thermal", "thermal_wns"])
def test_subset_pixels_are_the_full_arrays_pixels(name: str) -> None:
    scene = load_scene(name).with_noise(False)
    config = scene.sensor
    full = make_simulator(scene).simulate(N, np.random.default_rng(3))
    subset = make_simulator(scene, pixels=4).simulate(N, np.random.default_rng(3))
    # the pixels chosen: the generator's draw, then one uniform per pixel from the same stream
    rng = np.random.default_rng(3)
    TouchGenerator(config).draw(N, rng)
    pick = np.argsort(rng.random((N, config.n_pixels)), axis=1)[:, :4]
    assert set(subset) == set(full)
    rows = np.arange(N)[:, None]
    for key, values in full.items():
        np.testing.assert_array_equal(subset[key], values[rows, pick], err_msg=key)
    assert subset["readings"].shape == (N, 4, config.readout.n_samples)


def test_noisy_subsets_are_reproducible_and_keep_the_noise_level() -> None:
    scene = load_scene("thermal")
    a = simulate_shard(scene, 11, 0, N, pixels=4)
    b = simulate_shard(scene, 11, 0, N, pixels=4)
    for key in a:
        np.testing.assert_array_equal(a[key], b[key])
    clean = simulate_shard(scene.with_noise(False), 11, 0, N, pixels=4)
    # the same touches and pixels (the noise is drawn after them): the difference is the noise
    np.testing.assert_array_equal(a["latent_material"], clean["latent_material"])
    residual = a["readings"].astype(np.float64) - clean["readings"]
    noise = scene.sensor.readout.noise_k
    assert 0.8 * noise < residual.std() < 1.3 * noise


def test_take_pixels_gathers_per_pixel_arrays_and_keeps_per_touch_ones() -> None:
    config = load_scene("thermal").sensor
    touches = TouchGenerator(config).draw(5, np.random.default_rng(0))
    index = np.tile(np.array([[15, 0, 7]]), (5, 1))
    taken = take_pixels(touches, index)
    np.testing.assert_array_equal(taken["conductance"], touches["conductance"][:, [15, 0, 7]])
    np.testing.assert_array_equal(taken["ambient"], touches["ambient"])
    with pytest.raises(ValueError, match="pixel index"):
        take_pixels(touches, index + 1)
    with pytest.raises(ValueError, match="pixel index"):
        take_pixels(touches, index[0])


@pytest.mark.parametrize("pixels", [0, 17, 2.5, True])
def test_a_pixel_count_outside_the_array_is_refused(pixels: object) -> None:
    with pytest.raises(ConfigError, match="pixels"):
        make_simulator(load_scene("thermal"), pixels=pixels)  # type: ignore[arg-type]


def test_only_thermal_scenes_read_pixel_subsets() -> None:
    with pytest.raises(ConfigError, match="only thermal"):
        simulate_shard(load_scene("strips5"), 1, 0, 4, pixels=2)
    with pytest.raises(ConfigError, match="fast path"):
        make_simulator(load_scene("thermal"), reference=True, pixels=4)
