"""Train -> export -> runtime, on a tiny strips5 dataset: reproducible, resumable, parity-checked,
and the runtime works where torch cannot be imported."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed: nothing here runs without it")

import torch

from synth.dataset import generate
from synth.errors import ConfigError, DataError, InputError, ModelError
from synth.scene import load_scene
from tactile_learn.checkpoints import load_weights as load_run
from tactile_learn.export import PARITY_TOL, export
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.torch_estimator import TorchEstimator
from tactile_learn.train import TrainConfig, train

TRAIN_ARGS = ["--task", "strips", "--epochs", "3", "--batch-size", "64", "--seed", "5", "--threads", "1"]


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("strips5")
    scene = load_scene("strips5")
    generate(scene, 3000, 1, root / "train", shard_size=1000)
    generate(scene, 400, 2, root / "val")
    generate(scene, 400, 3, root / "test")
    return root


def _config(data: Path, out: str, **overrides: object) -> TrainConfig:
    """The tiny run's settings (3 epochs of 64-frame batches, seed 5), training into ``data/out``."""
    settings: dict[str, object] = {"epochs": 3, "batch_size": 64, "seed": 5, "threads": 1, **overrides}
    return TrainConfig(task="strips", data=str(data / "train"), val=str(data / "val"), out=str(data / out), **settings)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def run(data: Path) -> Path:
    train(_config(data, "run"), progress=False)
    return data / "run"


@pytest.fixture(scope="module")
def model(run: Path, data: Path) -> Path:
    export(run, data / "models" / "tiny.onnx", test=data / "test", command="pytest")
    return data / "models" / "tiny.onnx"


def test_training_writes_its_artifacts_and_learns(run: Path) -> None:
    metrics = json.loads((run / "metrics.json").read_text())
    assert {"train_seconds", "val_metrics", "history", "best_epoch"} <= set(metrics)
    assert (run / "loss.png").stat().st_size > 1000 and (run / "checkpoint.pt").exists()
    history = metrics["history"]
    assert history[-1]["train_loss"] < history[0]["train_loss"]
    assert metrics["val_metrics"]["pearson_r_mean"] > 0.8


def test_training_is_reproducible_for_a_seed(run: Path, data: Path) -> None:
    train(_config(data, "again"), progress=False)
    a, b = load_run(run)["state_dict"], load_run(data / "again")["state_dict"]
    assert all(torch.equal(a[k], b[k]) for k in a)


def test_killed_training_resumes_to_the_same_weights(run: Path, data: Path) -> None:
    out = data / "killed"
    argv = [
        "train",
        *TRAIN_ARGS,
        "--data",
        str(data / "train"),
        "--val",
        str(data / "val"),
        "--out",
        str(out),
        "--quiet",
    ]
    code = "import sys; from tactile_learn.cli import main; sys.exit(main(sys.argv[1:]))"
    proc = subprocess.Popen([sys.executable, "-c", code, *argv])
    deadline = time.monotonic() + 120
    while not (out / "checkpoint.pt").exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.01)
    time.sleep(0.3)  # into the second epoch
    os.kill(proc.pid, signal.SIGKILL)
    assert proc.wait() == -signal.SIGKILL, "training finished before it could be killed"
    assert not (out / "model.pt").exists()
    resumed = subprocess.run([sys.executable, "-c", code, *argv, "--resume"], capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    a, b = load_run(run)["state_dict"], load_run(out)["state_dict"]
    assert all(torch.equal(a[k], b[k]) for k in a)


def test_export_parity_card_and_runtime(model: Path, run: Path, data: Path) -> None:
    card = json.loads(model.with_suffix(".json").read_text())
    assert card["task"] == "strips" and card["opset"] >= 17
    assert card["inputs"][0]["shape"] == ["batch", 10] and card["outputs"][0]["shape"] == ["batch", 5, 5]
    assert card["parity"]["rel_err_b1"] <= PARITY_TOL and card["parity"]["rel_err_b7"] <= PARITY_TOL
    assert card["metrics"]["heldout"]["command"] == "pytest"
    assert card["metrics"]["heldout"]["data"]["seed"] == 3
    # nothing of the exporting machine ships: no source paths in the graph, no absolute paths in the card
    import tactile_learn

    source_root = str(Path(tactile_learn.__file__).resolve().parent.parent).encode()
    assert source_root not in model.read_bytes()
    assert str(data).encode() not in model.read_bytes()
    assert str(data) not in model.with_suffix(".json").read_text()
    saved = load_run(run)
    scene = load_scene("strips5")
    from tactile_learn.tasks import get_task

    net = get_task("strips").build_net(saved["size"], scene, saved["stats"])
    net.load_state_dict(saved["state_dict"])
    readings = np.load(data / "test" / "shard-00000.readings.npy")
    expected = TorchEstimator(net, "strips", scene).prepare().predict(readings)
    for threads in (1, 2):
        got = OnnxEstimator(model, threads=threads).prepare().predict(readings)
        assert np.abs(got - expected).max() <= PARITY_TOL * (expected.max() - expected.min())
    for batch in (0, 1, 7):
        assert OnnxEstimator(model).prepare().predict(readings[:batch]).shape == (batch, 5, 5)


def test_runtime_refuses_bad_models_and_inputs(model: Path, tmp_path: Path) -> None:
    est = OnnxEstimator(model).prepare()
    with pytest.raises(InputError, match="expected shape"):
        est.predict(np.full((2, 32), 0.3, np.float32))
    with pytest.raises(InputError, match="NaN"):
        est.predict(np.full((2, 10), np.nan, np.float32))
    blob = model.read_bytes()
    card = json.loads(model.with_suffix(".json").read_text())
    cases = {
        "truncated": (blob[: len(blob) // 2], card, "checksum differs"),
        "empty": (b"", card, "empty"),
        "no card": (blob, None, "model card not found"),
        "other card": (blob, {**card, "scene_digest": "0" * 16}, "scene"),
        "corrupt card": (blob, "{", "corrupt model card"),
    }
    for label, (onnx_bytes, card_data, fragment) in cases.items():
        path = tmp_path / f"{label.replace(' ', '_')}.onnx"
        path.write_bytes(onnx_bytes)
        if card_data is not None:
            text = card_data if isinstance(card_data, str) else json.dumps(card_data)
            path.with_suffix(".json").write_text(text)
        with pytest.raises(ModelError, match=fragment):
            OnnxEstimator(path).prepare().predict(np.full((1, 10), 0.3, np.float32))
    # a corrupt graph whose card was rewritten to match it: onnxruntime's own refusal, named
    garbage = tmp_path / "garbage.onnx"
    garbage.write_bytes(b"\x08\x07" + os.urandom(200))
    from synth.io import sha256_file

    garbage.with_suffix(".json").write_text(json.dumps({**card, "model_sha256": sha256_file(garbage)}))
    with pytest.raises(ModelError, match="cannot load"):
        OnnxEstimator(garbage).prepare().predict(np.full((1, 10), 0.3, np.float32))


def test_runtime_and_eval_work_without_torch(model: Path, data: Path) -> None:
    """A deployment has numpy + onnxruntime only: block torch and run both the API and the CLI."""
    code = f"""
import sys, json
sys.modules["torch"] = None  # any 'import torch' now raises ImportError
import numpy as np
from tactile_learn.runtime import OnnxEstimator
readings = np.load({str(data / "test" / "shard-00000.readings.npy")!r})
print(OnnxEstimator({str(model)!r}).prepare().predict(readings[:3]).shape)
from tactile_learn.cli import main
code = main(["eval", "--task", "strips", "--data", {str(data / "test")!r}, "--method", {str(model)!r}])
assert "torch" not in [m for m in sys.modules if sys.modules[m] is not None], "torch was imported"
sys.exit(code)
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "(3, 5, 5)" in result.stdout and '"pearson_r_mean"' in result.stdout


def test_exported_checks_match_numpy_and_the_flag_falls_back(model: Path, data: Path) -> None:
    """The graph's residual and balance are the numpy forward model's; frames above the card's
    thresholds are flagged and answered by the classical fallback."""
    from tactile_learn.estimators.classical.intersection import IntersectionEstimator
    from tactile_learn.strips_consistency import StripConsistency
    from tactile_learn.strips_guard import CheckedStripModel

    card = json.loads(model.with_suffix(".json").read_text())
    assert [o["name"] for o in card["outputs"]] == ["pressure", "residual", "balance"]
    thresholds = card["consistency"]["thresholds"]
    assert set(thresholds) == {"residual", "balance"} and all(v > 0 for v in thresholds.values())
    assert card["consistency"]["quantile"] == 0.99
    readings = np.load(data / "test" / "shard-00000.readings.npy")[:200]
    scene = load_scene("strips5")
    out = OnnxEstimator(model).prepare().predict_all(readings)
    consistency = StripConsistency(scene)
    numpy_residual = consistency.residual(readings, out["pressure"])["residual_sigma"]
    assert np.allclose(out["residual"], numpy_residual, rtol=1e-3, atol=1e-3)
    assert np.allclose(out["balance"], consistency.balance(readings), rtol=1e-3, atol=1e-5)
    # in-distribution frames: about 2 % flagged (each threshold is a 99th percentile of validation)
    checked = CheckedStripModel(model).prepare()
    result = checked.check(readings)
    assert result["flagged"].mean() < 0.08
    # thresholds below every value flag everything: the answer is then the intersection rule's
    strict = CheckedStripModel(model, thresholds={"residual": -1.0, "balance": -1.0}).prepare().check(readings)
    assert strict["flagged"].all()
    assert np.array_equal(strict["pressure"], IntersectionEstimator(scene).prepare().predict(readings))
    assert np.array_equal(strict["learned"], result["learned"])
    # frames this sensor cannot produce: one strip reads a heavy load no other strip confirms
    odd = readings[:50].copy()
    odd[:, 2] = scene.sensor.readout.offset_v + 1.2
    odd_check = checked.check(odd)
    assert odd_check["residual"].mean() > result["residual"].mean()
    assert odd_check["balance"].mean() > result["balance"].mean()
    assert odd_check["flagged"].mean() > 0.5
    # eval reports the flag, and the residual of every estimate
    from tactile_learn.tasks import get_task

    metrics = get_task("strips").evaluate(OnnxEstimator(model), get_task("strips").load_eval_data(data / "test"))
    assert 0 <= metrics["flag"]["flagged_share"] < 0.08 and "with_fallback" in metrics["flag"]
    assert metrics["residual_sigma_median"] == pytest.approx(metrics["flag"]["residual_median"], rel=0.05)


def test_fine_tuning_starts_from_the_given_weights(run: Path, data: Path) -> None:
    """--init: the first epoch starts where the run ended (validation no worse than a fresh start's
    first epoch), the normalisation is kept, and a mismatched size is refused."""
    from synth.errors import ConfigError

    base = load_run(run)
    config = _config(data, "tuned", epochs=1, seed=6, lr=1e-4, init=str(run))
    result = train(config, progress=False)
    tuned = load_run(data / "tuned")
    assert tuned["stats"] == base["stats"]
    assert result["val_metrics"]["pearson_r_mean"] >= base["result"]["val_metrics"]["pearson_r_mean"] - 0.01
    changed = [k for k in base["state_dict"] if not torch.equal(base["state_dict"][k], tuned["state_dict"][k])]
    assert changed  # it did train
    with pytest.raises(ConfigError, match="size"):
        train(dataclasses.replace(config, out=str(data / "bad"), size="large"), progress=False)


def test_a_validation_set_of_other_physics_is_refused_naming_the_difference(data: Path) -> None:
    quiet = dataclasses.replace(load_scene("strips5"), noise=False)
    generate(quiet, 50, 2, data / "val_quiet")
    with pytest.raises(
        DataError, match=r"differs from the training scene 'strips5' \(validation vs training: noise: False vs True\)"
    ):
        train(dataclasses.replace(_config(data, "run_quiet", epochs=1), val=str(data / "val_quiet")), progress=False)


def test_resuming_with_other_settings_names_them(run: Path, data: Path) -> None:
    changed = dataclasses.replace(_config(data, "run"), lr=0.5, batch_size=32)
    with pytest.raises(ConfigError, match=r"other settings \(batch_size: 64 then, 32 now; lr: .* then, 0\.5 now\)"):
        train(changed, resume=True, progress=False)
