"""Classical capacitive estimators, contact shapes and contact metrics on simple, known shapes."""

from __future__ import annotations

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.scene import Scene
from synth.stimuli import KINDS
from tactile_learn.calibration.capacitive import CapacitiveFrontEnd
from tactile_learn.contact_metrics import contact_metrics, separation
from tactile_learn.estimators.classical.capacitive import BicubicEstimator, DeconvolutionEstimator, bicubic_matrix
from tactile_learn.estimators.classical.contact_shapes import contact_shapes, moments
from tests.capacitive_scenes import tiny_capacitive_scene
from tests.tactile_learn.calibration.test_capacitive_calibration import true_table

METHODS = (BicubicEstimator, DeconvolutionEstimator)


def rectangle(
    shape: tuple[int, int], cx: float, cy: float, length: float, width: float, angle_deg: float
) -> np.ndarray:
    """A rotated rectangle's mask on pixels centred at (l + 0.5, k + 0.5), 4 x 4 sub-samples each."""
    sub = (np.arange(4) + 0.5) / 4
    ys = (np.arange(shape[0])[:, None] + sub[None, :]).ravel()
    xs = (np.arange(shape[1])[:, None] + sub[None, :]).ravel()
    y, x = np.meshgrid(ys, xs, indexing="ij")
    t = np.deg2rad(angle_deg)
    along = (x - cx) * np.cos(t) + (y - cy) * np.sin(t)
    across = -(x - cx) * np.sin(t) + (y - cy) * np.cos(t)
    inside = (np.abs(along) <= length / 2) & (np.abs(across) <= width / 2)
    return inside.reshape(shape[0], 4, shape[1], 4).mean(axis=(1, 3)) >= 0.5


@pytest.mark.parametrize("angle", [0.0, 30.0, 75.0, 120.0, 165.0])
def test_moments_give_a_rectangles_centre_orientation_and_elongation(angle: float) -> None:
    mask = rectangle((40, 40), 20.0, 19.0, 24.0, 6.0, angle)
    (shape,) = contact_shapes(mask.astype(float), mask, 0.5)
    assert shape.centroid_mm == pytest.approx((10.0, 9.5), abs=0.05)
    diff = abs(shape.orientation_deg - angle) % 180
    assert min(diff, 180 - diff) < 1.5
    assert shape.elongation == pytest.approx(4.0, rel=0.1)
    assert shape.area_mm2 == pytest.approx(24 * 6 * 0.25, rel=0.06)
    assert len(shape.outline) > 0 and mask[tuple(shape.outline.T)].all()


def test_two_blobs_are_two_contacts_and_round_ones_have_no_preferred_axis() -> None:
    mask = rectangle((30, 30), 8.0, 8.0, 6.0, 6.0, 0.0) | rectangle((30, 30), 22.0, 20.0, 4.0, 4.0, 0.0)
    shapes = contact_shapes(mask.astype(float), mask, 1.0)
    assert len(shapes) == 2 and shapes[0].area_mm2 > shapes[1].area_mm2
    assert all(s.elongation == pytest.approx(1.0, abs=0.05) for s in shapes)
    assert np.isnan(moments(np.zeros((4, 4)), 1.0)[2])


def test_bicubic_matrix_interpolates() -> None:
    up = bicubic_matrix(8, 4)
    assert np.allclose(up.sum(axis=1), 1.0)  # a constant stays constant
    ramp = np.arange(8.0)
    centres = (np.arange(32) + 0.5) / 4 - 0.5
    inner = (centres >= 1) & (centres <= 6)
    assert np.allclose((up @ ramp)[inner], centres[inner])  # and a ramp a ramp, away from the edges


@pytest.fixture(scope="module")
def blocks() -> tuple[Scene, np.ndarray, dict[str, np.ndarray]]:
    """Single frames of one elongated block each, noise and drift off, read with the true device."""
    kinds = [{"kind": "block", "force_n": [1.0, 2.5], "width_mm": [1.5, 2.0], "length_mm": [6.0, 8.0]}]
    scene = tiny_capacitive_scene(
        rows=8, cols=8, readout={"drift_v": 0.0, "drift_v_per_frame": 0.0}, stimuli={"frames": 1, "kinds": kinds}
    )
    scene = scene.with_noise(False)
    data = simulate_shard(scene, 4, 0, 16)
    loads = CapacitiveFrontEnd(scene.sensor, calibration=true_table(scene)).loads(data["readings"])[:, 0]
    return scene, loads, data


@pytest.mark.parametrize("method", METHODS)
def test_estimators_find_a_blocks_outline_centre_and_orientation(method: type, blocks: tuple) -> None:
    scene, loads, data = blocks
    est = method(scene).fit()
    state = dict(est.__dict__)
    pred = est.predict(loads)
    assert est.__dict__.keys() == state.keys() and all(est.__dict__[k] is v for k, v in state.items())
    assert pred.shape == (16, 2, 32, 32) and pred.dtype == np.float32 and (pred[:, 0] >= 0).all()
    kind = np.where(data["latent_kind"] >= 0, data["latent_kind"], -1)
    m = contact_metrics(
        pred, data["force_image"][:, 0], data["contact_mask"][:, 0], 0.45, kind=kind, n_contacts=np.ones(16, int)
    )
    assert m["iou_mean"] > 0.55
    assert m["centroid_err_mm_median"] < 0.25
    assert m["orientation_err_deg_median"] < 8.0
    assert m["by_kind"]["block"]["n_frames"] == 16 and set(m["by_kind"]) == {"block"}
    # the force image carries the contacts' force (the part the array feels)
    assert m["force_err_median"] < 0.15
    assert KINDS.index("block") in kind


@pytest.mark.parametrize("method", METHODS)
def test_idle_frames_show_no_contact(method: type) -> None:
    scene = tiny_capacitive_scene(rows=8, cols=8)
    rng = np.random.default_rng(1)
    from synth.sensors.capacitive.sensor import load_noise_n

    idle = (load_noise_n(scene.sensor) * rng.standard_normal((20, 8, 8))).astype(np.float32)
    pred = method(scene).fit().predict(idle)
    assert not (pred[:, 1] >= 0.5).any()


def test_metrics_of_a_perfect_and_of_a_merged_prediction() -> None:
    a = rectangle((32, 32), 8.0, 10.0, 8.0, 3.0, 20.0)
    b = rectangle((32, 32), 20.0, 10.0, 4.0, 4.0, 0.0)
    mask = np.stack([a, a | b])
    force = mask * 0.01
    perfect = np.stack([force, mask.astype(float)], axis=1)
    m = contact_metrics(perfect, force, mask, 0.45, kind=np.array([[2, -1], [2, 0]]), n_contacts=np.array([1, 2]))
    assert m["iou_mean"] == 1.0 and m["centroid_err_mm_median"] == 0.0 and m["orientation_err_deg_median"] == 0.0
    assert m["separation_rate"] == 1.0 and m["n_pairs"] == 1
    merged = mask.copy()
    merged[1, 9:11, 8:18] = True  # a bridge joins the two contacts
    eligible, gap, separated = separation(np.stack([force, merged.astype(float)], axis=1), mask, 0.45)
    assert eligible.tolist() == [False, True] and not separated[1] and gap[1] > 0
    # two predicted blobs, one over both contacts and a sliver of one: not a separation
    truth = np.zeros((1, 8, 16), dtype=bool)
    truth[0, 2:6, 2:6] = truth[0, 2:6, 8:14] = True
    pred = np.zeros((1, 2, 8, 16))
    pred[0, 1, 2:6, 2:11] = pred[0, 1, 2:6, 12:14] = 1.0
    assert not separation(pred, truth, 0.45)[2][0]
    pred[0, 1, 2:6, 6:8] = 0.0  # cut at the true gap: now each blob is one contact
    pred[0, 1, 2:6, 8:14] = 1.0
    assert separation(pred, truth, 0.45)[2][0]
    with pytest.raises(ValueError, match="does not match"):
        contact_metrics(perfect[:, :1], force, mask, 0.45)
