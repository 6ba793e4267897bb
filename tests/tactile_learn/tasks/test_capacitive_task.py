"""The capacitive task end to end: eval and bench from the CLI, data checks, and a tiny learned model
through training, ONNX export and the runtime."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from synth.config import dumps_toml
from synth.dataset import generate, simulate_shard
from synth.errors import DataError, InputError
from synth.io import atomic_save_npz
from synth.scene import Scene, load_scene
from tactile_learn.bench import bench_task
from tactile_learn.cli import main
from tactile_learn.tasks import get_task
from tests.capacitive_scenes import tiny_capacitive_scene


@pytest.fixture(scope="module")
def small(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Scene]:
    """A calibrated 8 x 8 scene (capacitive8's design and table) with short presses, and its data."""
    root = tmp_path_factory.mktemp("cap")
    data = load_scene("capacitive8").to_dict()
    data["name"] = "small"
    data["capacitive"]["stimuli"]["frames"] = 3
    (root / "small.toml").write_text(dumps_toml(data))
    scene = load_scene(root / "small.toml")
    generate(scene, 24, 3, root / "test")
    return root, scene


def test_eval_reports_shapes_by_kind_separation_and_the_front_ends_error(small: tuple[Path, Scene]) -> None:
    root, _ = small
    out = root / "eval.json"
    args = ["eval", "--task", "capacitive", "--data", str(root / "test"), "--method", "bicubic", "--reference"]
    assert main([*args, "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    m = result["metrics"]
    assert result["n_frames"] == 72
    assert 0.3 < m["iou_mean"] <= 1 and m["centroid_err_mm_median"] < 1.0
    assert set(m["by_kind"]) <= {"sphere", "punch", "block", "edge"} and m["by_kind"]
    assert "separation_rate" in m and "separation_by_gap_mm" in m
    err = m["cell_load_error"]
    assert err["loaded"]["median_g"] < 2.0 and err["idle"]["p95_g"] < 2.0  # the shipped calibration


def test_bench_runs_every_method_on_the_same_frames(small: tuple[Path, Scene]) -> None:
    root, _ = small
    # bicubic only: the deconvolution's batch-1024 throughput alone takes seconds (conformance covers it)
    result = bench_task("capacitive", n_frames=4, repeats=5, budget_s=0.1, data=str(root / "test"), methods=["bicubic"])
    (entry,) = result["methods"]
    assert entry["name"] == "bicubic" and entry["latency_us_p50_b1"] > 0 and "iou_mean" in entry["metrics"]
    assert result["n_frames"] == 4 and result["task"] == "capacitive"


def test_eval_data_checks(small: tuple[Path, Scene], tmp_path: Path) -> None:
    root, scene = small
    task = get_task("capacitive")
    arrays = simulate_shard(scene, 1, 0, 2)
    atomic_save_npz(tmp_path / "partial.npz", {"readings": arrays["readings"]})
    with pytest.raises(DataError, match="force_image"):
        task.load_eval_data(tmp_path / "partial.npz", scene)
    atomic_save_npz(tmp_path / "flat.npz", {**arrays, "readings": arrays["readings"][:, 0]})
    with pytest.raises(DataError, match="readings have shape"):
        task.load_eval_data(tmp_path / "flat.npz", scene)
    bad = arrays["readings"].copy()
    bad[0, 0, 0, 0] = np.nan
    atomic_save_npz(tmp_path / "nan.npz", {**arrays, "readings": bad})
    with pytest.raises(InputError, match="NaN"):
        task.load_eval_data(tmp_path / "nan.npz", scene)
    with pytest.raises(DataError, match=r"no capacitive"):
        task.load_eval_data(root / "test", load_scene("strips5"))


def test_a_tiny_learned_model_trains_exports_and_runs(small: tuple[Path, Scene]) -> None:
    pytest.importorskip("torch", reason="training needs torch")
    from tactile_learn.export import export
    from tactile_learn.runtime import OnnxEstimator
    from tactile_learn.train import TrainConfig, train

    root, scene = small
    generate(scene, 48, 1, root / "train")
    generate(scene, 8, 2, root / "val")
    config = TrainConfig(
        task="capacitive",
        data=str(root / "train"),
        val=str(root / "val"),
        out=str(root / "run"),
        epochs=2,
        batch_size=8,
        seed=3,
        threads=1,
    )
    result = train(config, progress=False)
    assert result["epochs_run"] == 2 and np.isfinite(result["val_metrics"]["iou_mean"])
    card = export(root / "run", root / "models" / "tiny_cap.onnx", test=root / "test", command="pytest")
    assert card["parity"]["rel_err_b7"] < 1e-4 and card["model_bytes"] < 5e6
    model = OnnxEstimator(root / "models" / "tiny_cap.onnx").prepare()
    loads = get_task("capacitive").load_eval_data(root / "test").inputs
    pred = model.predict(loads)
    assert pred.shape == (len(loads), 2, 32, 32) and ((pred[:, 1] >= 0) & (pred[:, 1] <= 1)).all()
    with pytest.raises(InputError, match="negative"):
        model.predict(np.full((1, 8, 8), -1.0, dtype=np.float32))
    # the model is for 8 x 8 arrays: another array size is refused by name
    other = tiny_capacitive_scene(rows=4, cols=3)
    with pytest.raises(Exception, match="shape"):
        OnnxEstimator(root / "models" / "tiny_cap.onnx", scene=other).prepare().predict(np.zeros((1, 4, 3), np.float32))


def test_the_shipped_model_reads_single_frames_of_its_device(tmp_path: Path) -> None:
    frames = load_scene("capacitive8_frames")
    assert frames.sensor.calibration == load_scene("capacitive8").sensor.calibration  # one device, one table
    generate(frames, 40, 5, tmp_path / "frames")
    out = tmp_path / "r.json"
    args = ["eval", "--task", "capacitive", "--data", str(tmp_path / "frames"), "--method", "capacitive8"]
    assert main([*args, "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["n_frames"] == 40 and result["metrics"]["iou_mean"] > 0.6
