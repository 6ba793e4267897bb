"""Strip layouts (synth.sensors.strip_layouts): diagonal strips, two-ended strips, taps - their
physics, their readings order, the estimators over every channel and the layout network."""

from __future__ import annotations

import numpy as np
import pytest

from synth.errors import ConfigError, InputError
from synth.scene import Scene, load_scene
from synth.sensors.strips import StripSensor, StripSimulator
from synth.sensors.strips.layouts import StripLayout
from tactile_learn.estimators.classical.projection import ProjectionEstimator
from tactile_learn.sweep import point_scene
from tactile_learn.tasks import get_task
from tactile_learn.tasks.strips import pairing
from tests.conftest import tiny_strips_scene

LAYOUTS = [
    {"strips.geometry.layout": "diagonal"},
    {"strips.geometry.layout": "diagonal", "strips.geometry.diagonals": "-45"},
    {"strips.geometry.layout": "diagonal", "strips.geometry.diagonals": "both"},
    {"strips.geometry.layout": "two_ended"},
    {"strips.geometry.layout": "taps", "strips.geometry.taps": 3},
]


def layout_scene(values: dict[str, object], base: Scene | None = None, **layers: float) -> Scene:
    scene = base if base is not None else tiny_strips_scene()
    extra = {f"strips.layers.{k}": v for k, v in layers.items()}
    return point_scene(scene, {**values, **extra})


def cell_field(sensor: StripSensor, cells: np.ndarray) -> np.ndarray:
    """The fine-lattice field of cell-constant pressures ``cells`` (B, N, M)."""
    s = sensor.array.s
    return np.repeat(np.repeat(cells, s, axis=1), s, axis=2).astype(np.float32)


def test_the_default_layout_is_the_orthogonal_pair_and_leaves_scenes_unchanged() -> None:
    scene = load_scene("strips16")
    assert scene.sensor.geometry.layout == "orthogonal"
    assert "layout" not in scene.to_dict()["strips"]["geometry"]  # digests of existing scenes unchanged
    # the general channel model reproduces the orthogonal readout it generalises
    sensor = StripSensor(tiny_strips_scene().sensor)
    rng = np.random.default_rng(1)
    row, col = rng.uniform(0, 80, (2, 4, 6, 5)).astype(np.float32)
    gains = rng.uniform(0.9, 1.1, (4, 11)).astype(np.float32)
    special = sensor.clean_readings(row, col, gains)
    general = sensor.readings_from_loads(sensor.channel_loads(np.stack([row, col], axis=1), gains))
    np.testing.assert_allclose(general, special, rtol=1e-6, atol=1e-6)


def test_readings_order_and_counts_follow_the_documentation() -> None:
    n, m = 6, 5
    for values, channels, groups in [
        ({"strips.geometry.layout": "orthogonal"}, n + m, ["rows", "cols"]),
        (LAYOUTS[0], n + m + (n + m - 1), ["rows", "cols", "diag+45"]),
        (LAYOUTS[2], n + m + 2 * (n + m - 1), ["rows", "cols", "diag+45", "diag-45"]),
        (LAYOUTS[3], 2 * (n + m), ["row_near", "row_far", "col_near", "col_far"]),
        (LAYOUTS[4], 3 * (n + m), ["row_sections", "col_sections"]),
    ]:
        scene = layout_scene(values)
        layout = StripLayout(scene.sensor.geometry)
        assert layout.n_channels == channels == scene.sensor.wire_count()
        assert [g.name for g in layout.groups] == groups
        out = StripSimulator(scene).simulate(3, np.random.default_rng(0))
        assert out["readings"].shape == (3, channels)
    # +45 strip k holds the cells with j - i = k - (N - 1): strip 0 is the corner cell (N-1, 0)
    layout = StripLayout(layout_scene(LAYOUTS[0]).sensor.geometry)
    first = layout.weights[layout.group("diag+45")][0, 2]
    assert first[n - 1, 0] == 1 and first.sum() == 1
    # taps: row i's section k at i T + k; sections tile the strip
    layout = StripLayout(layout_scene(LAYOUTS[4]).sensor.geometry)
    row2 = layout.weights[2 * 3 : 3 * 3, 0]
    assert np.array_equal(row2.sum(axis=0)[2], np.ones(m)) and row2.sum() == m


def test_a_diagonal_strip_reads_the_sum_of_the_pressure_along_its_diagonal() -> None:
    """Linear regime (p << p0) under a thin cover: a strip's load is sum p / p0 over its cells."""
    for values in (LAYOUTS[0], LAYOUTS[1]):
        scene = layout_scene(values, cover_mm=0.01, strip_thickness_mm=0.0)
        sensor = StripSensor(scene.sensor)
        rng = np.random.default_rng(4)
        cells = rng.uniform(0.0, 1.0, (3, 6, 5))  # kPa, p0 = 100 kPa
        loads = sensor.invert_readings(sensor.forward(cell_field(sensor, cells))["readings"])
        layout = sensor.layout
        group = layout.groups[2]
        weights = layout.weights[group.start : group.stop, 2]  # (D, N, M)
        expected = np.einsum("dnm,bnm->bd", weights, cells) / scene.sensor.piezo.p0_kpa
        np.testing.assert_allclose(loads[:, group.start : group.stop], expected, rtol=0.02, atol=2e-4)


def test_mirroring_the_pressure_turns_a_plus45_layer_into_a_minus45_layer() -> None:
    plus, minus = (StripSensor(layout_scene(v).sensor) for v in LAYOUTS[:2])
    rng = np.random.default_rng(5)
    field = rng.uniform(0, 60, (2, *plus.field_shape)).astype(np.float32)
    read_plus = plus.forward(field[:, :, ::-1])["readings"][:, 11:]  # x mirrored
    read_minus = minus.forward(field)["readings"][:, 11:]
    np.testing.assert_allclose(read_plus, read_minus[:, ::-1], rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("values", LAYOUTS, ids=lambda v: "-".join(str(x) for x in v.values()))
def test_mirrors_permute_the_channels_as_the_training_augmentation_assumes(values: dict[str, object]) -> None:
    sensor = StripSensor(layout_scene(values).sensor)
    rng = np.random.default_rng(6)
    field = rng.uniform(0, 60, (2, *sensor.field_shape)).astype(np.float32)
    readings = sensor.forward(field)["readings"]
    for flip_y, flip_x in ((True, False), (False, True), (True, True)):
        perm = sensor.layout.flip_permutation(flip_y, flip_x)
        if perm is None:  # one flip maps a single diagonal layer onto the other direction
            assert values.get("strips.geometry.layout") == "diagonal" and flip_y != flip_x
            continue
        mirrored = field[:, :: -1 if flip_y else 1, :: -1 if flip_x else 1]
        np.testing.assert_allclose(sensor.forward(mirrored)["readings"], readings[:, perm], rtol=1e-5, atol=1e-5)


def test_two_ended_strips_give_the_load_and_its_position_along_the_strip() -> None:
    base = tiny_strips_scene(count=[1, 1], margin_mm=4.0).with_noise(False)
    two = layout_scene(LAYOUTS[3], base)
    out = StripSimulator(two).simulate(40, np.random.default_rng(7))
    one = StripSimulator(base).simulate(40, np.random.default_rng(7))  # the same contacts and gains
    sensor = StripSensor(two.sensor)
    loads = sensor.invert_readings(out["readings"])
    n, m = 6, 5
    near, far = loads[:, :n], loads[:, n : 2 * n]
    # near + far is the strip's load of a one-ended readout
    orth = StripSensor(base.sensor).invert_readings(one["readings"])
    np.testing.assert_allclose((near + far)[:, :], orth[:, :n], rtol=1e-3, atol=1e-4)
    np.testing.assert_allclose(loads[:, 2 * n : 2 * n + m] + loads[:, 2 * n + m :], orth[:, n:], rtol=1e-3, atol=1e-4)
    # far / (near + far) on the most loaded row: the contact's x along the strip
    pitch = two.sensor.geometry.pitch_mm
    row = np.argmax(near + far, axis=1)
    b = np.arange(len(row))
    position = far[b, row] / (near[b, row] + far[b, row]) * m * pitch
    x = out["latent_xy_mm"][:, 0, 0]
    assert np.abs(position - x).max() < 0.35 * pitch
    assert np.corrcoef(position, x)[0, 1] > 0.98


def test_tapped_sections_add_up_to_the_strip() -> None:
    base = tiny_strips_scene(count=[1, 2]).with_noise(False)
    tapped = layout_scene(LAYOUTS[4], base)
    loads = StripSensor(tapped.sensor).invert_readings(
        StripSimulator(tapped).simulate(20, np.random.default_rng(8))["readings"]
    )
    orth = StripSensor(base.sensor).invert_readings(
        StripSimulator(base).simulate(20, np.random.default_rng(8))["readings"]
    )
    np.testing.assert_allclose(loads[:, :18].reshape(20, 6, 3).sum(axis=2), orth[:, :6], rtol=1e-3, atol=1e-4)


def test_bad_layout_settings_and_readings_are_named() -> None:
    with pytest.raises(ConfigError, match="taps"):
        layout_scene({"strips.geometry.layout": "taps", "strips.geometry.taps": 9})
    with pytest.raises(ConfigError, match="layout"):
        layout_scene({"strips.geometry.layout": "hexagonal"})
    scene = layout_scene(LAYOUTS[0])
    with pytest.raises(InputError, match="readings"):
        ProjectionEstimator(scene).prepare().predict(np.full((2, 11), 0.3, np.float32))  # orthogonal readings


def test_a_diagonal_layer_pairs_two_identical_contacts() -> None:
    """The ghost case: the orthogonal pair cannot tell the diagonals apart, one diagonal layer can."""
    twins = load_scene("strips16_twins")
    ratios = {}
    for name, scene in (("orthogonal", twins), ("diagonal", load_scene("strips16_twins_diagonal"))):
        out = StripSimulator(scene).simulate(40, np.random.default_rng(11))
        pred = ProjectionEstimator(scene).prepare().predict(out["readings"])
        extra = {k: v for k, v in out.items() if k.startswith("latent_")}
        ratios[name] = pairing(pred, extra, 2.5)["ghost_to_real_median"]
    assert ratios["orthogonal"] > 0.9  # as much on the ghosts as on the real crossings
    assert ratios["diagonal"] < 0.2


def test_layout_network_reads_any_layout() -> None:
    torch = pytest.importorskip("torch")
    from tactile_learn.nets.strips_layout import LayoutLoads

    task = get_task("strips")
    for values in LAYOUTS:
        scene = layout_scene(values)
        out = StripSimulator(scene).simulate(64, np.random.default_rng(9))
        sensor = StripSensor(scene.sensor)
        graph = LayoutLoads(scene)(torch.from_numpy(out["readings"])).numpy()
        np.testing.assert_allclose(graph, sensor.invert_readings(out["readings"]), rtol=1e-4, atol=1e-4)
        stats = task.fit_stats(out, scene)
        net = task.build_net("small", scene, stats)
        x, targets = task.training_batch(out, scene, np.random.default_rng(0))
        assert net(torch.from_numpy(x)).shape == targets["pressure"].shape
        card = task.input_layout(scene)
        assert card["layout"] == values["strips.geometry.layout"]
        assert sum(g["count"] for g in card["order"]) == sensor.n_channels


def test_a_sweep_point_sets_the_layout() -> None:
    from tactile_learn.sweep import wire_count

    scene = point_scene(load_scene("strips16"), {"strips.geometry.layout": "two_ended"})
    assert scene.sensor.geometry.layout == "two_ended" and wire_count(scene) == 64
    assert scene.to_dict()["strips"]["geometry"]["layout"] == "two_ended"
