"""The contact-shape library (synth.stimuli) and the mixed training scene: force conservation,
shapes against their definitions, symmetry, limits, held-out parameter intervals."""

from __future__ import annotations

import numpy as np
import pytest

from synth.errors import ConfigError
from synth.scene import load_scene, parse_scene
from synth.sensors.strips import StripSimulator
from synth.sensors.strips.config import allowed_intervals, draw_except
from synth.stimuli import KINDS, ContactBatch, rasterize, window_cells
from tests.conftest import tiny_strips_scene
from tests.paths import REPO_ROOT

#: parameter ranges whose footprints stay within 4.5 mm of the centre (the user-field forward only
#: sees the array's own lattice)
NEW_KINDS = {
    "ring": {"radius_mm": [0.3, 4.0], "hole_fraction": [0.0, 0.8]},
    "terminal": {"radius_mm": [0.5, 2.0], "hole_fraction": [0.3, 0.7], "width_mm": [0.3, 2.0], "length_mm": [0.5, 2.0]},
    "blob": {"radius_mm": [0.1, 2.0], "width_mm": [0.1, 0.8]},
    "block": {"width_mm": [0.2, 3.0], "length_mm": [0.5, 5.0], "tilt": [-1.0, 1.0]},
}


def one_contact(kind: str, h: float = 0.25, size: int = 80, **params: float) -> np.ndarray:
    """The window of one contact at the centre of a fine lattice (kPa)."""
    defaults = {"force_n": 2.0, "radius_mm": 4.0, "width_mm": 3.0, "length_mm": 6.0, "angle_deg": 0.0}
    defaults.update(params)
    detail = np.asarray(defaults.pop("detail", np.linspace(0.05, 0.95, 12)), dtype=np.float64)[None]
    fields = {
        k: np.array([defaults.get(k, 0.0)])
        for k in ("force_n", "radius_mm", "width_mm", "length_mm", "angle_deg", "hole_fraction", "tilt")
    }
    centre = (size // 2) * h
    batch = ContactBatch(x_mm=np.array([centre]), y_mm=np.array([centre]), detail=detail, **fields)
    return rasterize(kind, batch, h, size, e_star_mpa=1.3).values[0]


@pytest.mark.parametrize("kind", sorted(NEW_KINDS))
def test_new_kinds_match_the_full_field_forward(kind: str) -> None:
    spec = {"kind": kind, "force_n": [0.05, 6.0], "angle_deg": [0.0, 360.0], **NEW_KINDS[kind]}
    scene = tiny_strips_scene(kinds=[spec], count=[0, 3], margin_mm=4.6).with_noise(False)
    scene = scene.with_outputs(("readings", "pressure", "field", "latent"))
    sim = StripSimulator(scene)
    out = sim.simulate(48, np.random.default_rng(4))
    carried = out["field"].sum(axis=(1, 2)) * sim.sensor.field_pitch_mm**2 / 1000
    assert np.allclose(carried, out["latent_force_n"].sum(axis=1), rtol=1e-4)
    again = sim.sensor.forward(out["field"], gains=out["latent_strip_gain"])
    assert np.allclose(out["readings"], again["readings"], atol=2e-5)
    assert np.allclose(out["pressure"], again["pressure"], rtol=1e-4, atol=1e-3)
    assert (out["field"] >= 0).all() and np.isfinite(out["readings"]).all()


@pytest.mark.parametrize("kind", ["ring", "terminal", "blob", "block"])
def test_every_new_kind_conserves_force_at_any_size(kind: str) -> None:
    """Large, tiny and degenerate contacts alike carry exactly their force (the window is sized for
    each contact; sub-cell contacts fall back to a point load)."""
    rng = np.random.default_rng(8)
    n = 64
    params = {
        "force_n": rng.uniform(0.0, 8.0, n),
        "radius_mm": np.exp(rng.uniform(np.log(0.01), np.log(12.0), n)),
        "width_mm": np.exp(rng.uniform(np.log(0.01), np.log(6.0), n)),
        "length_mm": np.exp(rng.uniform(np.log(0.01), np.log(20.0), n)),
        "angle_deg": rng.uniform(0, 360, n),
        "hole_fraction": rng.uniform(0, 0.95, n),
        "tilt": rng.uniform(-1, 1, n),
    }
    contacts = ContactBatch(
        x_mm=rng.uniform(10, 20, n), y_mm=rng.uniform(10, 20, n), detail=rng.random((n, 12)), **params
    )

    h = 0.625
    size = int(window_cells(kind, contacts, h, 1.3).max())
    windows = rasterize(kind, contacts, h, size, 1.3)
    carried = windows.values.sum(axis=(1, 2)) * h * h / 1000
    assert np.allclose(carried, params["force_n"], rtol=1e-9, atol=1e-12)
    assert (windows.values >= 0).all() and np.isfinite(windows.values).all()


def test_ring_is_an_annulus_of_uniform_pressure() -> None:
    h = 0.25
    ring = one_contact("ring", h=h, radius_mm=4.0, hole_fraction=0.5, force_n=2.0)
    y, x = (np.indices(ring.shape) + 0.5) * h - 40 * h
    r = np.hypot(x, y)
    pressure = 2.0 * 1000 / (np.pi * (4.0**2 - 2.0**2))  # kPa
    assert np.allclose(ring[(r > 2.3) & (r < 3.7)], pressure, rtol=1e-3)  # 3 x 3 sub-samples per cell
    assert not ring[r < 1.7].any() and not ring[r > 4.3].any()
    assert np.allclose(ring, ring[::-1, :]) or np.allclose(ring[1:, :], ring[1:, :][::-1, :])  # mirror symmetric
    disc = one_contact("ring", h=h, radius_mm=4.0, hole_fraction=0.0)
    assert disc[r < 3.7].min() > 0  # no hole at all


def test_tilted_block_profile_and_centroid() -> None:
    h = 0.25
    flat = one_contact("block", h=h, width_mm=3.0, length_mm=8.0, tilt=0.0)
    tilted = one_contact("block", h=h, width_mm=3.0, length_mm=8.0, tilt=1.0)
    _, x = (np.indices(flat.shape) + 0.5) * h - 40 * h
    assert (flat > 0).sum() == (tilted > 0).sum() + np.count_nonzero((flat > 0) & (tilted == 0))
    # p ~ 1 + t s / (l/2): the centre of pressure moves t l / 6 towards the high end
    shift = (tilted * x).sum() / tilted.sum() - (flat * x).sum() / flat.sum()
    assert shift == pytest.approx(8.0 / 6, abs=0.05)
    row = tilted[40, 26:54]
    assert np.all(np.diff(row[row > 0]) > 0)  # rising linearly along the block
    mirrored = one_contact("block", h=h, width_mm=3.0, length_mm=8.0, tilt=-1.0)
    assert np.allclose(mirrored, tilted[:, ::-1], rtol=1e-6, atol=1e-9)


def test_terminal_is_a_ring_plus_a_tongue() -> None:
    h = 0.25
    ring = one_contact("ring", h=h, radius_mm=3.0, hole_fraction=0.5)
    terminal = one_contact("terminal", h=h, radius_mm=3.0, hole_fraction=0.5, width_mm=2.0, length_mm=5.0)
    y, x = (np.indices(ring.shape) + 0.5) * h - 40 * h
    tongue = (x > 3.2) & (x < 7.8) & (np.abs(y) < 0.8)
    assert terminal[tongue].min() > 0 and not ring[tongue].any()
    assert not terminal[(x < -3.3)].any()  # the tongue points along +x (angle 0) only
    assert not terminal[np.hypot(x, y) < 1.3].any()  # the hole stays open


def test_blob_is_smooth_and_compact() -> None:
    h = 0.25
    blob = one_contact("blob", h=h, radius_mm=3.0, width_mm=1.0)
    y, x = (np.indices(blob.shape) + 0.5) * h - 40 * h
    assert not blob[np.hypot(x, y) > 3.0 + 3.0 + h].any()  # bumps within radius, cut at 3 widths
    assert (blob >= 0).all() and blob.max() > 0
    # band-limited: neighbouring cells differ little compared with the peak
    assert np.abs(np.diff(blob, axis=1)).max() < 0.35 * blob.max()
    other = one_contact("blob", h=h, radius_mm=3.0, width_mm=1.0, detail=np.linspace(0.9, 0.1, 12))
    assert not np.allclose(blob, other)  # the detail numbers shape it


def test_kind_codes_only_grow() -> None:
    assert KINDS[:4] == ("sphere", "punch", "block", "edge")


def test_holdout_intervals_are_never_drawn_and_the_rest_is_uniform() -> None:
    u = np.random.default_rng(0).random(200_000)
    holes = [(25.0, 35.0), (55.0, 65.0)]
    draws = draw_except(u, 0.0, 180.0, holes)
    assert not ((draws > 25.0) & (draws < 35.0)).any() and not ((draws > 55.0) & (draws < 65.0)).any()
    assert draws.min() >= 0.0 and draws.max() <= 180.0
    counts, _ = np.histogram(draws, bins=[0, 25, 35, 55, 65, 180])
    assert counts[1] == counts[3] == 0
    assert counts[0] / counts[4] == pytest.approx(25 / 115, rel=0.03)
    assert np.array_equal(draw_except(u, 1.0, 3.0, []), 1.0 + u * 2.0)  # no holes: the plain draw
    assert allowed_intervals(0.0, 10.0, [(-5.0, 2.0), (8.0, 20.0)]) == [(2.0, 8.0)]


def test_holdout_config_errors_name_the_problem() -> None:
    data = load_scene("strips16").to_dict()
    data["strips"]["stimuli"]["kinds"][0]["holdout"] = [{"parameter": "radius_mm", "lo": 2.0, "hi": 9.0}]
    with pytest.raises(ConfigError, match="cover its whole range"):
        parse_scene(data)
    data["strips"]["stimuli"]["kinds"][0]["holdout"] = [{"parameter": "radius_mm", "lo": 5.0, "hi": 4.0}]
    with pytest.raises(ConfigError, match="empty"):
        parse_scene(data)
    data["strips"]["stimuli"]["kinds"][0]["holdout"] = [{"parameter": "colour", "lo": 4.0, "hi": 5.0}]
    with pytest.raises(ConfigError, match="parameter"):
        parse_scene(data)


def test_mixed_scene_draws_the_whole_library_and_respects_its_holdouts() -> None:
    scene = load_scene("strips16_mixed")
    stimuli = scene.sensor.stimuli
    assert {k.kind for k in stimuli.kinds} == set(KINDS)
    assert stimuli.count == (1, 4) and 0 < stimuli.empty_fraction < 0.1
    assert any(k.kind == "block" and k.tilt == (-1.0, 1.0) for k in stimuli.kinds)
    sim = StripSimulator(scene.with_outputs(("latent",)))
    out = sim.simulate(3000, np.random.default_rng(1))
    kind = out["latent_kind"]
    counts = out["latent_n_contacts"]
    assert set(np.unique(counts)) == {0, 1, 2, 3, 4}
    angles = out["latent_angle_deg"][kind == KINDS.index("edge")]
    assert len(angles) > 100 and not ((angles > 40) & (angles < 50)).any()
    radii = out["latent_radius_mm"][kind == KINDS.index("ring")]
    assert len(radii) > 100 and not ((radii > 4.5) & (radii < 5.5)).any()
    # the suite's held-out parameters lie inside these intervals (see test_suites.py)


def test_old_scenes_draw_and_store_what_they_did() -> None:
    """strips16 uses none of the new kinds: no new latent arrays, and its digest is unchanged (the
    shipped cards were written against it)."""
    import json

    scene = load_scene("strips5")
    out = StripSimulator(scene).simulate(8, np.random.default_rng(0))
    assert "latent_tilt" not in out and "latent_detail" not in out
    card = json.loads((REPO_ROOT / "models" / "strips5.json").read_text())
    assert card["scene_digest"] == scene.digest
