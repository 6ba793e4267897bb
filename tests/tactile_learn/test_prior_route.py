"""Routed model cards (tactile_learn.prior_route, OnnxEstimator's ``route`` block): each frame is answered
by the model the router picks, in every path (batch, single frames, every output, streams), the folded
router equals its unfolded arithmetic, and a missing, corrupt or mismatched member is refused by name.

The routed pair here is built from two shipped strip models of the same sensor and outputs (``strips16``
as the card's own graph, ``strips16_small`` as the generic member) and a router whose one live hidden unit
reads the log of the frame's total load: frames loaded above a chosen total go to the member, so which
frames are routed where is known without the router's training.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.errors import InputError, ModelError
from synth.io import sha256_file
from synth.scene import load_scene
from tactile_learn.frame_stream import FrameStream
from tactile_learn.prior_route import PriorRoute, route_features
from tactile_learn.runtime import OnnxEstimator
from tests.paths import REPO_ROOT

MODELS = REPO_ROOT / "models"
OFFSET, SCALE = 0.3, 16.0


def frames(n: int = 160, seed: int = 11) -> np.ndarray:
    scene = load_scene("strips16_mixed")
    return np.asarray(simulate_shard(scene, seed, 0, n)["readings"], dtype=np.float32)


def total_router(log_total_cut: float, hidden: int = 8) -> dict[str, np.ndarray]:
    """A router whose logit is ``log(total load) - log_total_cut``: generic above that total."""
    n = 32
    arrays = {
        "mean": np.zeros(n + 1),
        "std": np.ones(n + 1),
        "w0": np.zeros((hidden, n + 1)),
        "b0": np.zeros(hidden),
        "w1": np.zeros((hidden, hidden)),
        "b1": np.zeros(hidden),
        "w2": np.zeros((1, hidden)),
        "b2": np.array([-log_total_cut - 20.0]),
    }
    # hidden unit 0: log T + 20 (> 0 for any total above 2e-9: the ReLU passes it), carried through layer 2
    arrays["w0"][0, n], arrays["b0"][0] = 1.0, 20.0
    arrays["w1"][0, 0] = 1.0
    arrays["w2"][0, 0] = 1.0
    return arrays


def routed_folder(folder: Path, arrays: dict[str, np.ndarray], threshold: float = 0.5, **edits: Any) -> Path:
    """``folder/routed.onnx``: strips16's graph routing to a copy of strips16_small by ``arrays``."""
    folder.mkdir(parents=True, exist_ok=True)
    for stem, name in (("strips16", "routed"), ("strips16_small", "member")):
        for suffix in (".onnx", ".json"):
            shutil.copy(MODELS / f"{stem}{suffix}", folder / f"{name}{suffix}")
    PriorRoute.save(folder / "route.npz", arrays)
    card = json.loads((folder / "routed.json").read_text())
    card["route"] = {
        "generic_model": "member.onnx",
        "router": "route.npz",
        "router_sha256": sha256_file(folder / "route.npz"),
        "offset": OFFSET,
        "share_scale": SCALE,
        "threshold": threshold,
    } | edits
    (folder / "routed.json").write_text(json.dumps(card))
    return folder / "routed.onnx"


@pytest.fixture(scope="module")
def readings() -> np.ndarray:
    return frames()


@pytest.fixture(scope="module")
def cut(readings: np.ndarray) -> float:
    """A total load that splits the frames about in half."""
    totals = np.clip(readings - OFFSET, 0.0, None).sum(axis=1)
    return float(np.log(np.median(totals)))


@pytest.fixture(scope="module")
def routed(tmp_path_factory: pytest.TempPathFactory, cut: float) -> OnnxEstimator:
    return OnnxEstimator(routed_folder(tmp_path_factory.mktemp("routed"), total_router(cut))).prepare()


@pytest.fixture(scope="module")
def members() -> tuple[OnnxEstimator, OnnxEstimator]:
    scene = load_scene("strips16_mixed")
    own = OnnxEstimator(MODELS / "strips16.onnx", route=False).prepare()  # (the shipped card routes too)
    generic = OnnxEstimator(MODELS / "strips16_small.onnx", scene=own.scene_).prepare()
    assert scene.task == "strips"
    return own, generic


def expected_split(readings: np.ndarray, cut: float) -> np.ndarray:
    return np.asarray(np.log(np.clip(readings - OFFSET, 0.0, None).sum(axis=1)) >= cut)


def test_the_router_sends_the_frames_its_logit_says(routed: OnnxEstimator, readings: np.ndarray, cut: float) -> None:
    generic = routed.route_[0].generic(readings)
    assert 0.3 < generic.mean() < 0.7  # the split this test relies on
    near = np.abs(np.log(np.clip(readings - OFFSET, 0.0, None).sum(axis=1)) - cut) < 1e-5
    assert np.array_equal(generic[~near], expected_split(readings, cut)[~near])
    assert [routed.route_[0].generic_frame(f[None]) for f in readings] == generic.tolist()


def test_every_path_answers_each_frame_by_the_model_the_router_picks(
    routed: OnnxEstimator, members: tuple[OnnxEstimator, OnnxEstimator], readings: np.ndarray
) -> None:
    own, member = members
    generic = routed.route_[0].generic(readings)
    batch = routed.predict(readings)
    assert np.array_equal(batch[generic], member.predict(readings[generic]))
    assert np.array_equal(batch[~generic], own.predict(readings[~generic]))
    # single frames: each member's own single-frame result, bit for bit
    for i in range(0, len(readings), 7):
        frame = readings[i : i + 1]
        expected = (member if generic[i] else own).predict(frame)
        assert np.array_equal(routed.predict(frame), expected)
    everything = routed.predict_all(readings)
    assert set(everything) == {"pressure", "residual", "balance"}
    for name, values in everything.items():
        assert np.array_equal(values[generic], member.predict_all(readings[generic])[name]), name
        assert np.array_equal(values[~generic], own.predict_all(readings[~generic])[name]), name


def test_a_stream_routes_each_frame_as_predict_does(routed: OnnxEstimator, readings: np.ndarray) -> None:
    plain, gated = FrameStream(routed), FrameStream(routed, gate=True)
    answered = 0
    for i in range(0, len(readings), 5):
        frame = readings[i : i + 1]
        assert np.array_equal(plain.predict(frame), routed.predict(frame)), i
        out = gated.predict(frame)  # the idle gate answers frames at rest with an empty map
        if out.any():
            answered += 1
            assert np.array_equal(out, routed.predict(frame)), i
    assert answered >= 10
    run = routed.one_frame_run()
    assert run is not None
    assert np.array_equal(run(readings[3:4]), routed.predict(readings[3:4]))
    runner = routed.frame_runner()
    assert runner is not None
    assert np.array_equal(runner(readings[4:5]), routed.predict(readings[4:5]))


def test_all_frames_to_one_side_and_an_empty_batch(tmp_path: Path, readings: np.ndarray) -> None:
    everything_generic = OnnxEstimator(routed_folder(tmp_path / "all", total_router(-50.0))).prepare()
    member = OnnxEstimator(MODELS / "strips16_small.onnx", scene=everything_generic.scene_).prepare()
    assert everything_generic.route_[0].generic(readings).all()
    assert np.array_equal(everything_generic.predict(readings), member.predict(readings))
    assert everything_generic.predict(readings[:0]).shape == (0, 16, 16)
    assert {k: v.shape for k, v in everything_generic.predict_all(readings[:0]).items()} == {
        "pressure": (0, 16, 16),
        "residual": (0,),
        "balance": (0,),
    }


def test_bad_frames_get_the_usual_errors_whichever_way_they_would_go(
    routed: OnnxEstimator, readings: np.ndarray
) -> None:
    for bad in (np.nan, np.inf, -1.0):
        frame = readings[:2].copy()
        frame[0, 3] = bad
        with pytest.raises(InputError):
            routed.predict(frame)
        with pytest.raises(InputError):
            routed.predict(frame[:1])
    with pytest.raises(InputError):
        routed.predict(readings[:1, :31])


def test_the_folded_router_equals_its_unfolded_arithmetic(tmp_path: Path, readings: np.ndarray) -> None:
    rng = np.random.default_rng(5)
    arrays = {
        "mean": rng.normal(0.5, 0.3, 33),
        "std": rng.uniform(0.2, 2.0, 33),
        "w0": rng.normal(0, 0.3, (24, 33)),
        "b0": rng.normal(0, 0.1, 24),
        "w1": rng.normal(0, 0.3, (24, 24)),
        "b1": rng.normal(0, 0.1, 24),
        "w2": rng.normal(0, 0.3, (1, 24)),
        "b2": rng.normal(0, 0.1, 1),
    }
    PriorRoute.save(tmp_path / "r.npz", arrays)
    route = PriorRoute.load(tmp_path / "r.npz", sha256_file(tmp_path / "r.npz"), 32, OFFSET, SCALE, 0.5)
    x = np.concatenate([readings, np.full((1, 32), 0.1, np.float32)])  # and a frame at rest
    z = (route_features(x, OFFSET, SCALE).astype(np.float64) - arrays["mean"]) / arrays["std"]
    h = np.maximum(z @ arrays["w0"].T + arrays["b0"], 0.0)
    h = np.maximum(h @ arrays["w1"].T + arrays["b1"], 0.0)
    unfolded = (h @ arrays["w2"].T + arrays["b2"])[:, 0]
    assert np.allclose(route.logit(x), unfolded, rtol=1e-4, atol=1e-4)
    clear = np.abs(unfolded) > 1e-3
    assert np.array_equal(route.generic(x)[clear], (unfolded >= 0.0)[clear])
    assert [route.generic_frame(f[None]) for f in x] == route.generic(x).tolist()
    assert math.isclose(PriorRoute(arrays, OFFSET, SCALE, 0.8).logit_threshold, math.log(4.0))


def test_a_missing_corrupt_or_mismatched_member_is_refused(tmp_path: Path, cut: float) -> None:
    arrays = total_router(cut)

    for name, edits, match in (
        ("fields", {"router": None}, "router"),
        ("threshold", {"threshold": 1.0}, "threshold"),
        ("number", {"offset": "a lot"}, "numbers"),
        ("checksum", {"router_sha256": "0" * 64}, "checksum"),
        ("nowhere", {"router": "elsewhere.npz"}, "not found"),
        ("member", {"generic_model": "missing.onnx"}, "not found"),
    ):
        path = routed_folder(tmp_path / name, arrays, **edits)
        if edits.get("router", "") is None:
            card = json.loads(path.with_suffix(".json").read_text())
            del card["route"]["router"]
            path.with_suffix(".json").write_text(json.dumps(card))
        with pytest.raises(ModelError, match=match):
            OnnxEstimator(path).prepare()
    # a router of another width, a router file cut short
    path = routed_folder(tmp_path / "shape", {**arrays, "w1": np.zeros((8, 7))})
    with pytest.raises(ModelError, match="w1"):
        OnnxEstimator(path).prepare()
    path = routed_folder(tmp_path / "short", arrays)
    data = (path.parent / "route.npz").read_bytes()
    (path.parent / "route.npz").write_bytes(data[: len(data) // 2])
    card = json.loads(path.with_suffix(".json").read_text())
    card["route"]["router_sha256"] = sha256_file(path.parent / "route.npz")
    path.with_suffix(".json").write_text(json.dumps(card))
    with pytest.raises(ModelError, match="cannot read the router"):
        OnnxEstimator(path).prepare()
    # a member with other outputs (strips16_spheres gives the map only), a member that routes itself
    path = routed_folder(tmp_path / "outputs", arrays)
    for suffix in (".onnx", ".json"):
        shutil.copy(MODELS / f"strips16_spheres{suffix}", path.parent / f"member{suffix}")
    with pytest.raises(ModelError, match=r"does not match this card.s (inputs|outputs)"):
        OnnxEstimator(path).prepare()
    path = routed_folder(tmp_path / "nested", arrays)
    member_card = json.loads(path.with_suffix(".json").read_text())
    member_card["route"]["generic_model"] = "routed.onnx"
    shutil.copy(path, path.parent / "member.onnx")
    (path.parent / "member.json").write_text(json.dumps(member_card))
    with pytest.raises(ModelError, match="routes frames itself"):
        OnnxEstimator(path).prepare()


def test_route_false_runs_the_cards_own_graph_on_every_frame(
    routed: OnnxEstimator, members: tuple[OnnxEstimator, OnnxEstimator], readings: np.ndarray
) -> None:
    own, _ = members
    alone = OnnxEstimator(routed.path, route=False).prepare()
    assert alone.route_ is None and routed.route_ is not None
    assert routed.route_[0].generic(readings).any()  # the routed card answers some frames otherwise
    np.testing.assert_array_equal(alone.predict(readings), own.predict(readings))
    np.testing.assert_array_equal(alone.predict(readings[:1]), own.predict(readings[:1]))
