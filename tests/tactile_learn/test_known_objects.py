"""Known-objects bundles (tactile_learn.known_objects, train_known_objects, ``tactile-learn objects``): each frame
is answered by the model the router picks, the router's numpy arithmetic equals its unfolded float64 form,
a corrupt or mismatched bundle is refused by name, and a built bundle's threshold keeps its promise on the
held-out frames it was chosen on.

The hand-made bundles here use two shipped strip models of one sensor as stand-in specialists
(``strips16_small`` and ``strips16_spheres``) beside the default ``strips16``, and routers whose weights are
set by hand, so which frame goes where is known without training.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from synth.dataset import generate, load_arrays, simulate_shard
from synth.errors import ConfigError, InputError, ModelError, TactileError
from synth.io import sha256_file
from synth.scene import load_scene
from synth.suite import load_suite
from tactile_learn.cli import main
from tactile_learn.known_objects import DEFAULT, KnownObjects, ObjectRouter, choose, read_bundle
from tactile_learn.methods import resolve_method
from tactile_learn.prior_route import PriorRoute, route_features
from tests.paths import REPO_ROOT

MODELS = REPO_ROOT / "models"
OFFSET, SCALE = 0.3, 16.0
STAND_INS = {"ring": "strips16_small", "pair": "strips16_spheres"}


def frames(n: int = 120, seed: int = 5) -> np.ndarray:
    return np.asarray(simulate_shard(load_scene("strips16_mixed"), seed, 0, n)["readings"], dtype=np.float32)


def random_router(classes: int, hidden: int = 8, seed: int = 0, scale: float = 1.0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    n = 32
    return {
        "mean": rng.normal(size=n + 1),
        "std": rng.uniform(0.5, 2.0, size=n + 1),
        "w0": rng.normal(size=(hidden, n + 1)) * scale,
        "b0": rng.normal(size=hidden),
        "w1": rng.normal(size=(hidden, hidden)) * scale,
        "b1": rng.normal(size=hidden),
        "w2": rng.normal(size=(classes, hidden)) * scale,
        "b2": rng.normal(size=classes),
    }


def bundle_folder(
    folder: Path,
    arrays: dict[str, np.ndarray],
    accept: float = 0.5,
    stand_ins: dict[str, str] = STAND_INS,
    **edits: Any,
) -> Path:
    """A bundle of ``stand_ins`` (object name -> shipped model standing in for its specialist) with ``arrays`` as
    its router; ``edits`` replace bundle fields."""
    folder.mkdir()
    objects = {}
    for name, model in stand_ins.items():
        shutil.copyfile(MODELS / f"{model}.onnx", folder / f"{name}.onnx")
        shutil.copyfile(MODELS / f"{model}.json", folder / f"{name}.json")
        objects[name] = f"{name}.onnx"
    PriorRoute.save(folder / "router.npz", arrays)
    bundle = {
        "format": 1,
        "kind": "known_objects",
        "task": "strips",
        "default": "strips16",
        "objects": objects,
        "router": "router.npz",
        "router_sha256": sha256_file(folder / "router.npz"),
        "offset": OFFSET,
        "share_scale": SCALE,
        "accept": accept,
    } | edits
    (folder / "bundle.json").write_text(json.dumps(bundle))
    return folder / "bundle.json"


def unfolded_probabilities(arrays: dict[str, np.ndarray], readings: np.ndarray) -> np.ndarray:
    a = {k: np.asarray(v, dtype=np.float64) for k, v in arrays.items()}
    x = (route_features(readings, OFFSET, SCALE).astype(np.float64) - a["mean"]) / a["std"]
    h = np.maximum(x @ a["w0"].T + a["b0"], 0.0)
    h = np.maximum(h @ a["w1"].T + a["b1"], 0.0)
    z = h @ a["w2"].T + a["b2"]
    e = np.exp(z - z.max(axis=1, keepdims=True))
    return e / e.sum(axis=1, keepdims=True)


def test_the_router_equals_its_unfolded_float64_arithmetic() -> None:
    arrays = random_router(3)
    x = frames()
    router = ObjectRouter(arrays, OFFSET, SCALE, ("ring", "pair"))
    prob = router.probabilities(x)
    assert prob.dtype == np.float32 and prob.shape == (len(x), 3)
    np.testing.assert_allclose(prob, unfolded_probabilities(arrays, x), atol=2e-5)
    np.testing.assert_allclose(prob.sum(axis=1), 1.0, atol=1e-5)


def test_no_valid_frame_gives_nan_and_a_bad_one_goes_to_the_default() -> None:
    router = ObjectRouter(random_router(3, scale=30.0), OFFSET, SCALE, ("ring", "pair"))
    extreme = np.stack([np.full(32, OFFSET), np.zeros(32), np.full(32, 1e4), np.r_[np.full(31, OFFSET), 50.0]])
    prob = router.probabilities(extreme.astype(np.float32))
    assert np.isfinite(prob).all()  # logits far apart (weights x30): the shifted softmax never overflows
    bad = frames(2)
    bad[0, 3] = np.nan
    assert router.choose(bad, 0.5)[0] == 2


def test_a_frame_goes_to_the_most_probable_known_object_only_above_accept() -> None:
    prob = np.array([[0.7, 0.2, 0.1], [0.3, 0.6, 0.1], [0.1, 0.1, 0.8], [0.45, 0.1, 0.45]])
    np.testing.assert_array_equal(choose(prob, 2, 0.5), [0, 1, 2, 2])
    np.testing.assert_array_equal(choose(prob, 2, 0.65), [0, 2, 2, 2])


def test_each_frame_is_answered_by_the_model_the_router_picks(tmp_path: Path) -> None:
    path = bundle_folder(tmp_path / "b", random_router(3, seed=1), accept=0.5)  # splits 41 / 74 / 85
    est = resolve_method("strips", str(path), load_scene("strips16"))
    assert isinstance(est, KnownObjects)
    x = frames(200)
    names = est.route(x)
    assert {str(n) for n in names} == {"ring", "pair", DEFAULT}, "the hand-set router must split this batch"
    before = {k: v for k, v in vars(est).items()}
    out = est.predict(x)
    assert {k: v for k, v in vars(est).items()}.keys() == before.keys()
    models = {n: resolve_method("strips", m, load_scene("strips16")) for n, m in STAND_INS.items()}
    models[DEFAULT] = resolve_method("strips", "strips16", load_scene("strips16"))
    for name, model in models.items():
        rows = names == name
        np.testing.assert_allclose(out[rows], model.predict(x[rows]), rtol=0, atol=1e-6)
    # the folder names the same bundle; one frame gives its row of the batch
    same = resolve_method("strips", str(tmp_path / "b"), load_scene("strips16"))
    np.testing.assert_allclose(same.predict(x[7:8]), out[7:8], atol=1e-6)


def test_bad_input_gets_the_default_models_error(tmp_path: Path) -> None:
    est = KnownObjects(bundle_folder(tmp_path / "b", random_router(3))).prepare()
    x = frames(4)
    x[1, 0] = np.nan
    with pytest.raises(InputError, match="NaN"):
        est.predict(x)
    with pytest.raises(InputError):
        est.predict(frames(4)[:, :30])


@pytest.mark.parametrize(
    ("edits", "message"),
    [
        ({"kind": "model"}, "not a known-objects bundle"),
        ({"format": 2}, "bundle format 2"),
        ({"task": "fsr"}, "route strips readings, not 'fsr'"),
        ({"accept": 1.0}, r"accept 1.0 must be a probability in \[0.5, 1\)"),
        ({"accept": 0.2}, "must be a probability"),
        ({"offset": float("nan")}, "must be finite numbers"),
        ({"objects": {}}, "must map each object's name"),
        ({"objects": {"default": "ring.onnx"}}, "cannot name an object"),
        ({"objects": {"ring": "missing.onnx", "pair": "pair.onnx"}}, "model of object 'ring'"),
        ({"router_sha256": "0" * 64}, "checksum differs"),
        ({"default": "no_such_model"}, "default model 'no_such_model' is not found"),
    ],
)
def test_a_corrupt_or_mismatched_bundle_is_refused_by_name(tmp_path: Path, edits: dict[str, Any], message: str) -> None:
    path = bundle_folder(tmp_path / "b", random_router(3), **edits)
    with pytest.raises(TactileError, match=message):
        KnownObjects(path).prepare()


def test_a_router_of_another_set_of_objects_or_a_missing_field_is_refused(tmp_path: Path) -> None:
    path = bundle_folder(tmp_path / "b", random_router(4))  # three objects + other, the bundle lists two
    with pytest.raises(ModelError, match=r"router array w2 has shape \(4, 8\), expected \(3, 8\)"):
        KnownObjects(path).prepare()
    bundle = json.loads(path.read_text())
    del bundle["router"]
    path.write_text(json.dumps(bundle))
    with pytest.raises(ModelError, match="the bundle lacks router"):
        read_bundle(path)
    path.write_text("{not json")
    with pytest.raises(ModelError, match="cannot read the bundle"):
        read_bundle(tmp_path / "b")
    with pytest.raises(ModelError, match="bundle not found"):
        read_bundle(tmp_path / "nowhere")


def write_family(suite: str, family: str, n: int, seed: int, out: Path) -> Path:
    generate(load_suite(suite).family(family).scene, n, seed, out)
    return out


def stand_in_specialist(folder: Path, data: Path) -> Path:
    """The small shipped model with a card naming ``data`` as its training set."""
    folder.mkdir()
    shutil.copyfile(MODELS / "strips16_small.onnx", folder / "specialist.onnx")
    card = json.loads((MODELS / "strips16_small.json").read_text())
    card["training"]["data"] = {"path": str(data)}
    (folder / "specialist.json").write_text(json.dumps(card))
    return folder / "specialist.onnx"


def test_objects_builds_a_bundle_whose_threshold_keeps_its_promise(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("torch", reason="torch (training extra) is not installed")
    from tactile_learn.train_known_objects import build_bundle

    suite = "strips16_unseen4"
    ring = write_family(suite, "bead_loop", 70, 31, tmp_path / "d-ring")
    corner = write_family(suite, "card_corner", 70, 32, tmp_path / "d-corner")
    other = write_family(suite, "ruler_edge", 70, 33, tmp_path / "d-other")
    spec = stand_in_specialist(tmp_path / "s-ring", ring)
    out = tmp_path / "bundle"
    argv = ["objects", "--object", f"ring={spec}", "--object", f"corner={tmp_path / 's-ring' / 'specialist.onnx'}"]
    argv += ["--data", f"corner={corner}", "--other", str(other), "--out", str(out)]
    argv += ["--train-frames", "50", "--other-frames", "50", "--val-frames", "20", "--false-share", "0.1"]
    assert main(argv) == 0
    bundle = json.loads((out / "bundle.json").read_text())
    assert bundle["objects"] == {"ring": "ring.onnx", "corner": "corner.onnx"}
    assert (
        bundle["command"].startswith("tactile-learn objects --object ring=")
        and "--false-share 0.1" in bundle["command"]
    )
    assert bundle["calibrate_on"] == "frames"  # one --other dataset: its held-out frames
    est = resolve_method("strips", str(out), load_scene("strips16"))
    held_other = stored_readings(other)[-20:]
    routed = np.mean(est.route(held_other) != DEFAULT)
    assert routed <= 0.1 and np.isclose(routed, bundle["validation"]["other_routed_share"])
    assert 0.5 <= bundle["accept"] < 1.0
    held_ring = stored_readings(ring)[-20:]
    own = bundle["validation"]["objects"]["ring"]["to_own_specialist"]
    assert np.isclose(np.mean(est.route(held_ring) == "ring"), own)
    # a bundle is never overwritten; a --data for no object and a bad pair are refused by name
    written = (out / "bundle.json").read_bytes()
    with pytest.raises(ConfigError, match="exists: choose another folder"):
        build_bundle({"ring": spec}, [other], out)
    assert (out / "bundle.json").read_bytes() == written
    bad = ["objects", "--object", f"ring={spec}", "--data", f"cup={ring}", "--other", str(other), "--out", "x"]
    assert main(bad) == 2
    assert "--data names no --object: cup" in capsys.readouterr().err
    assert main(["objects", "--object", "ring", "--other", str(other), "--out", str(tmp_path / "y")]) == 2
    assert "expected NAME=PATH" in capsys.readouterr().err
    assert not (tmp_path / "y").exists()


def stored_readings(folder: Path) -> np.ndarray:
    return np.asarray(load_arrays(folder, ["readings"])["readings"], dtype=np.float32)


def test_single_frames_take_their_members_one_frame_path_with_the_same_answers_and_errors(tmp_path: Path) -> None:
    est = KnownObjects(bundle_folder(tmp_path / "b", random_router(3, seed=1))).prepare()
    x = frames(40)
    batch = est.predict(x)
    names = est.route(x)
    assert len(set(names.tolist())) == 3
    for i in range(len(x)):
        # (one frame and a batch run different float32 kernels: equal to rounding)
        np.testing.assert_allclose(est.predict(x[i : i + 1]), batch[i : i + 1], rtol=1e-5, atol=1e-5)
    bad = x[:1].copy()
    bad[0, 5] = np.inf
    with pytest.raises(InputError, match=r"inf|finite"):
        est.predict(bad)
    with pytest.raises(InputError):
        est.predict(-x[:1])


def test_one_frames_choice_is_the_batch_choice() -> None:
    x = frames(300)
    for seed in (1, 3, 6):
        router = ObjectRouter(random_router(3, seed=seed, scale=2.0), OFFSET, SCALE, ("ring", "pair"))
        for accept in (0.5, 0.7, 0.9):
            batch = router.choose(x, accept)
            assert [router.choose_frame(x[i : i + 1], accept) for i in range(len(x))] == batch.tolist()
    bad = x[:1].copy()
    bad[0, 0] = np.nan
    assert router.choose_frame(bad, 0.5) == 2


def test_a_router_that_cannot_keep_the_promise_writes_no_bundle(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("torch", reason="torch (training extra) is not installed")
    import tactile_learn.train_known_objects as fit

    data = write_family("strips16_unseen4", "bead_loop", 30, 41, tmp_path / "d")
    spec = stand_in_specialist(tmp_path / "s", data)
    monkeypatch.setattr(fit, "accept_for", lambda top, share: 1.0)
    with pytest.raises(ConfigError, match="cannot tell them from the known objects"):
        fit.build_bundle(
            {"ring": spec},
            [data],
            tmp_path / "out",
            train_frames=10,
            other_frames=10,
            val_frames=10,
            calibrate_on="frames",
        )
    assert not (tmp_path / "out").exists()


def test_the_threshold_is_chosen_on_datasets_the_router_never_trains_on(tmp_path: Path) -> None:
    from tactile_learn.train_known_objects import other_frames_for

    folders = [write_family("strips16_unseen4", f, 30, 50 + i, tmp_path / f) for i, f in enumerate(
        ("bead_loop", "card_corner", "ruler_edge")
    )]  # fmt: skip
    frames = {f: stored_readings(f) for f in folders}
    train, held = other_frames_for(folders, 40, 10, "datasets")
    np.testing.assert_array_equal(train, np.concatenate([frames[folders[0]][:20], frames[folders[2]][:20]]))
    np.testing.assert_array_equal(held, frames[folders[1]][-10:])
    train, held = other_frames_for(folders, 30, 5, "frames")
    np.testing.assert_array_equal(held, np.concatenate([frames[f][-5:] for f in folders]))
    assert len(train) == 30
    with pytest.raises(ConfigError, match="at least two --other datasets"):
        other_frames_for(folders[:1], 10, 5, "datasets")
    with pytest.raises(ConfigError, match="expected one of datasets, frames"):
        other_frames_for(folders, 10, 5, "objects")
