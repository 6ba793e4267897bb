"""Object tomography (tactile_learn.object_tomography): the pose search finds the pose a frame was made at,
the fit explains frames of a shape it was never given better than its start and recovers that shape, bad
readings are refused by name, idle and saturated frames are left out and counted, and a template file
round-trips while a corrupt or foreign one is refused."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="object tomography fits with torch (the train extra)")

from synth.errors import ConfigError, DataError, InputError  # noqa: E402
from synth.scene import load_scene  # noqa: E402
from synth.sensors.strips.physics import StripSensor  # noqa: E402
from tactile_learn.learn_object import render_frames  # noqa: E402
from tactile_learn.object_tomography import (  # noqa: E402
    ObjectTemplate,
    TomographyConfig,
    _centres,
    _profiles,
    _shift_matrices,
    best_poses,
    fit_template,
    frame_loads,
    readable_object_frames,
    rotated,
)

SCENE = load_scene("strips16")
SIZE = 64


def l_shape() -> np.ndarray:
    """An L with a knob: no rotation of it equals another, nor its mirror image."""
    t = np.zeros((SIZE, SIZE), np.float32)
    t[20:24, 14:46] = 1.0
    t[24:44, 14:18] = 1.0
    t[36:40, 36:40] = 2.0
    return t / t.sum()


def object_of(t: np.ndarray) -> ObjectTemplate:
    centres = np.array([[32, 32], [24, 40], [40, 26], [30, 20]])
    return ObjectTemplate(t, centres, np.array([3.0, 5.0, 8.0, 4.0]), np.zeros(4, np.float32), 0.625, SCENE.digest)


def aligned_r(fitted: np.ndarray, truth: np.ndarray) -> float:
    """The best Pearson r of the fitted template against the truth over rotations (5 degrees), mirror
    images and circular shifts."""
    angles = torch.arange(72, dtype=torch.float32) * (2 * math.pi / 72)
    b = truth - truth.mean()
    fb = np.conj(np.fft.fft2(b))
    best = -1.0
    for image in (fitted, fitted[:, ::-1].copy()):
        for rot in rotated(torch.from_numpy(image), angles).numpy():
            a = rot - rot.mean()
            cc = np.real(np.fft.ifft2(np.fft.fft2(a) * fb))
            best = max(best, float(cc.max() / (np.linalg.norm(a) * np.linalg.norm(b))))
    return best


def test_pose_search_finds_the_pose_each_frame_was_made_at() -> None:
    t = torch.from_numpy(l_shape())
    centres = _centres(SIZE, 16, 4)
    rows_at, cols_at = _shift_matrices(SIZE, 16, 4, centres), _shift_matrices(SIZE, 16, 4, centres)
    angles = torch.arange(24, dtype=torch.float32) * (2 * math.pi / 24)
    qr, qc = _profiles(t, angles, rows_at, cols_at)
    rng = np.random.default_rng(0)
    a = rng.integers(0, 24, 40)
    y = rng.integers(20, len(centres) - 20, 40)
    x = rng.integers(20, len(centres) - 20, 40)
    scale = rng.uniform(0.5, 3.0, 40)[:, None]
    rows = torch.from_numpy((qr[a, y].numpy() * scale).astype(np.float32))
    cols = torch.from_numpy((qc[a, x].numpy() * scale).astype(np.float32))
    got_a, got_y, got_x, residual = best_poses(t, angles, rows_at, cols_at, rows, cols, chunk=7)
    assert (got_a == a).all() and (got_y == y).all() and (got_x == x).all()
    assert residual.max() < 1e-3


def test_fit_recovers_a_shape_from_its_readings_alone() -> None:
    truth = l_shape()
    frames = render_frames(object_of(truth), SCENE.with_noise(False), 240, np.random.default_rng(1), vary=0.0)
    readings, counts = readable_object_frames(frames["readings"], SCENE.sensor, min_frames=200)
    assert counts["used"] == 240
    config = TomographyConfig(size=SIZE, angles=36, iterations=12, steps=40)
    fitted = fit_template(readings, SCENE.sensor, SCENE.digest, config)
    history = [h["residual_median"] for h in fitted.history]
    assert history[-1] < 0.5 * history[0]
    # the start (a round blob) is no L; the fit is, up to rotation, mirror image and place
    blob = np.exp(-((np.mgrid[0:SIZE, 0:SIZE] - 31.5) ** 2).sum(0) / (2 * 6.4**2)).astype(np.float32)
    assert aligned_r(fitted.template, truth) > 0.6 > aligned_r(blob, truth) + 0.15
    assert fitted.template.shape == (SIZE, SIZE) and np.isclose(fitted.template.sum(), 1.0, atol=1e-5)
    assert (fitted.template >= 0).all() and np.isfinite(fitted.residual).all()
    assert len(fitted.centres) == len(fitted.total_load) == 240


def test_the_same_seed_fits_the_same_template() -> None:
    frames = render_frames(object_of(l_shape()), SCENE, 60, np.random.default_rng(2), vary=0.2)
    config = TomographyConfig(size=32, angles=12, iterations=2, steps=5, seed=3)
    a = fit_template(frames["readings"], SCENE.sensor, SCENE.digest, config)
    b = fit_template(frames["readings"], SCENE.sensor, SCENE.digest, config)
    assert np.array_equal(a.template, b.template) and np.array_equal(a.centres, b.centres)


def test_bad_readings_are_refused_by_name() -> None:
    good = render_frames(object_of(l_shape()), SCENE, 30, np.random.default_rng(3), vary=0.0)["readings"]
    with pytest.raises(InputError, match="shape"):
        readable_object_frames(good[:, :20], SCENE.sensor)
    for bad in (np.nan, np.inf, -0.5, 9.0):
        x = good.copy()
        x[4, 7] = bad
        with pytest.raises(InputError, match="readings"):
            readable_object_frames(x, SCENE.sensor)
    with pytest.raises(InputError, match="at least 31"):
        readable_object_frames(good, SCENE.sensor, min_frames=31)
    with pytest.raises(ConfigError, match="orthogonal"):
        readable_object_frames(good, load_scene("strips16_twins_diagonal").sensor)


def test_idle_and_saturated_frames_are_left_out_and_counted() -> None:
    sensor = StripSensor(SCENE.sensor)
    pressed = render_frames(object_of(l_shape()), SCENE, 20, np.random.default_rng(4), vary=0.0)["readings"]
    idle = sensor.forward(np.zeros((5, *sensor.field_shape)), rng=np.random.default_rng(5), noise=True)["readings"]
    saturated = pressed[:3].copy()
    saturated[:, 2] = SCENE.sensor.readout.full_scale_v
    kept, counts = readable_object_frames(np.concatenate([pressed, idle, saturated]), SCENE.sensor)
    assert counts == {"frames": 28, "idle": 5, "saturated": 3, "used": 20}
    assert np.array_equal(kept, pressed.astype(np.float32))
    _, _, total = frame_loads(kept, sensor)
    assert (total > 0).all()


def test_template_file_round_trips_and_corrupt_files_are_refused(tmp_path: Path) -> None:
    obj = object_of(l_shape())
    path = obj.save(tmp_path / "t.npz")
    back = ObjectTemplate.load(path)
    assert np.allclose(back.template, obj.template) and np.array_equal(back.centres, obj.centres)
    assert back.scene_digest == SCENE.digest and back.cell_mm == 0.625
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(path.read_bytes()[:300])
    with pytest.raises(DataError, match=r"truncated\.npz"):
        ObjectTemplate.load(truncated)
    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, template=obj.template)
    with pytest.raises(DataError, match="not an object template"):
        ObjectTemplate.load(foreign)
    negative = ObjectTemplate(-obj.template, obj.centres, obj.total_load, obj.residual, 0.625, "x")
    with pytest.raises(DataError, match="non-negative"):
        ObjectTemplate.load(negative.save(tmp_path / "negative.npz"))
    with pytest.raises(DataError, match="no such"):
        ObjectTemplate.load(tmp_path / "missing.npz")


@pytest.mark.parametrize(
    "kwargs", [{"size": 15}, {"size": 63}, {"angles": 2}, {"iterations": 0}, {"lr": 0.0}, {"smooth": -1.0}]
)
def test_out_of_range_settings_are_refused(kwargs: dict[str, float]) -> None:
    with pytest.raises(ConfigError):
        TomographyConfig(**kwargs)  # type: ignore[arg-type]
