"""The streaming fast path and the idle gate (tactile_learn.frame_stream, tactile_learn.idle)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.errors import InputError, ModelError
from synth.scene import load_scene
from tactile_learn.cli import main
from tactile_learn.frame_stream import FrameStream
from tactile_learn.fsr_check import JOINT_STARTS_MAX, one_press_check
from tactile_learn.idle import IdleGate, idle_scene, measure_idle_floor
from tactile_learn.methods import resolve_method
from tactile_learn.runtime import OnnxEstimator
from tests.paths import REPO_ROOT

MODELS = REPO_ROOT / "models"


class CountingModel(OnnxEstimator):
    """The shipped model, recording every frame that reaches the network."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.seen: list[np.ndarray] = []

    def predict_checked(self, x: np.ndarray) -> np.ndarray:
        self.seen.append(x.copy())
        return super().predict_checked(x)


def mixed_stream(idle_share: float, n: int = 400, seed: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Strip readings: ``idle_share`` of them the sensor at rest, the rest two-sphere frames."""
    scene = load_scene("strips16")
    n_idle = round(idle_share * n)
    idle = simulate_shard(idle_scene(scene), seed, 0, n_idle)["readings"]
    busy = simulate_shard(scene, seed, 1, n - n_idle)["readings"]
    order = np.random.default_rng(seed).permutation(n)
    frames = np.concatenate([idle, busy])[order]
    return np.ascontiguousarray(frames, dtype=np.float32), (order >= n_idle)


def test_idle_frames_never_reach_the_network() -> None:
    frames, touched = mixed_stream(0.8)
    model = CountingModel(MODELS / "strips16.onnx")
    stream = FrameStream(model, gate=True)
    out = np.concatenate([stream.predict(frames[i : i + 1]) for i in range(len(frames))])
    reached = np.concatenate(model.seen)
    active = stream.gate.active(frames)  # type: ignore[union-attr]
    # the network saw exactly the active frames, in order; every frame at rest was skipped
    np.testing.assert_array_equal(reached, frames[active])
    assert not active[~touched].any()
    assert stream.skipped == int((~active).sum()) >= int((~touched).sum())
    assert (out[~active] == 0).all()


def test_gated_results_equal_ungated_on_active_frames() -> None:
    frames, _ = mixed_stream(0.5, n=200)
    model = OnnxEstimator(MODELS / "strips16.onnx").prepare()
    gated = FrameStream(model, gate=True)
    result = gated.predict(frames)  # one mixed batch: only its active frames go to the network
    active = gated.gate.active(frames)  # type: ignore[union-attr]
    assert 0 < active.sum() < len(frames)
    np.testing.assert_array_equal(result[active], model.predict(frames[active]))
    np.testing.assert_allclose(result[active], model.predict(frames)[active], rtol=1e-5, atol=1e-5)
    singles = np.concatenate([gated.predict(frames[i : i + 1]) for i in np.flatnonzero(active)])
    np.testing.assert_allclose(singles, result[active], rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize(
    ("task", "method", "scene_name"),
    [
        ("strips", "intersection", "strips16"),
        ("strips", "strips16", "strips16"),
        ("fsr", "triangulation", "fsr6"),
        ("fsr", "fsr", "fsr6"),
        ("capacitive", "capacitive8", "capacitive8"),
    ],
)
def test_stream_equals_predict_and_refuses_bad_input(task: str, method: str, scene_name: str) -> None:
    from tactile_learn.tasks import get_task

    scene = load_scene(scene_name)
    task_obj = get_task(task)
    x = np.asarray(task_obj.example_inputs(simulate_shard(scene, 3, 0, 24), scene), dtype=np.float32)
    est = resolve_method(task, method, scene)
    stream = FrameStream(est)
    np.testing.assert_array_equal(stream.predict(x), est.predict(x))
    for i in range(3):
        np.testing.assert_array_equal(stream.predict(x[i : i + 1]), est.predict(x[i : i + 1]))
    np.testing.assert_array_equal(stream.predict(x[:2].astype(np.float64)), est.predict(x[:2]))  # slow path
    bad: list[tuple[Any, str]] = [(x[0], "batch axis"), (x[:, :-1], "shape")]
    nan = x[:2].copy()
    nan.reshape(2, -1)[1, 0] = np.nan
    bad.append((nan, "NaN"))
    inf = x[:1].copy()
    inf.reshape(1, -1)[0, -1] = np.inf
    bad.append((inf, "NaN or inf"))
    low, high, _ = task_obj.fast_bounds(scene)  # type: ignore[misc]
    below = x[:1].copy()
    below.reshape(1, -1)[0, 0] = low - 1.0
    bad.append((below, "frame 0"))
    if np.isfinite(high):
        above = x[:1].copy()
        above.reshape(1, -1)[0, 0] = high
        bad.append((above, "saturated"))
    for frames, words in bad:
        with pytest.raises(InputError, match=words):
            stream.predict(frames)


def test_idle_floor_in_cards_and_gate_errors(tmp_path: Path) -> None:
    for name in ("strips16", "fsr", "capacitive8"):
        card = json.loads((MODELS / f"{name}.json").read_text())
        assert card["idle"]["threshold"] > 2.0
    scene = load_scene("strips16")
    rest = simulate_shard(idle_scene(scene), 77, 0, 500)["readings"]
    gate = IdleGate.from_floor(measure_idle_floor(scene, n=2000, seed=8), 32)
    assert gate.active(rest).mean() < 0.01  # frames at rest (another seed) are idle
    touched = simulate_shard(scene, 77, 1, 200)["readings"]
    assert gate.active(touched).mean() > 0.99  # two spheres of >= 0.5 N are never idle
    with pytest.raises(ModelError, match="idle floor has 32 values"):
        IdleGate.from_floor(measure_idle_floor(scene, n=200), 33)
    # a model whose card lacks the floor: a clear error naming the fix
    for suffix in (".onnx", ".json"):
        (tmp_path / f"m{suffix}").write_bytes((MODELS / f"strips16{suffix}").read_bytes())
    card = json.loads((tmp_path / "m.json").read_text())
    del card["idle"]
    (tmp_path / "m.json").write_text(json.dumps(card))
    with pytest.raises(ModelError, match=r"idle_floor\.py"):
        FrameStream(OnnxEstimator(tmp_path / "m.onnx", route=False), gate=True)  # (its routed member stays behind)


def test_run_cli_writes_predictions_and_skips_idle(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    frames, touched = mixed_stream(0.8, n=100)
    np.savez(tmp_path / "frames.npz", readings=frames)
    args = ["run", "--task", "strips", "--method", "strips16", "--frames", str(tmp_path / "frames.npz")]
    assert main([*args, "--out", str(tmp_path / "g.npz"), "--json", str(tmp_path / "s.json")]) == 0
    assert main([*args, "--out", str(tmp_path / "u.npz"), "--gate", "off"]) == 0
    gated, ungated = np.load(tmp_path / "g.npz"), np.load(tmp_path / "u.npz")
    stats = json.loads((tmp_path / "s.json").read_text())
    assert stats["frames"] == 100 and stats["skipped"] == int((~gated["active"]).sum()) >= 80
    np.testing.assert_allclose(gated["pressure"][touched], ungated["pressure"][touched], rtol=1e-5, atol=1e-5)
    np.savez(tmp_path / "bad.npz", pressure=frames)
    assert main([*args[:-1], str(tmp_path / "bad.npz"), "--out", str(tmp_path / "x.npz")]) == 2
    assert "'readings'" in capsys.readouterr().err


def test_one_press_check_flags_do_not_depend_on_the_batch() -> None:
    scene = load_scene("fsr6")
    readings = simulate_shard(scene, 11, 0, 8 * JOINT_STARTS_MAX)["readings"].astype(np.float32)
    estimate = resolve_method("fsr", "triangulation", scene).predict(readings)[:, :5]
    check = one_press_check(scene)
    assert one_press_check(scene) is check  # set up once per scene
    batch = check.p_one_press(readings, estimate)  # many doubtful frames: one start after the other
    singles = np.concatenate([check.p_one_press(readings[i : i + 1], estimate[i : i + 1]) for i in range(len(batch))])
    np.testing.assert_array_equal(batch, singles)  # few: both starts at once
    assert (batch == 1).any() and (batch == 0).any()
