"""Learning an object from its readings (tactile_learn.learn_object, ``tactile-learn learn-object``): rendered
frames are reproducible by seed and carry the observed loads, the command writes a working specialist with a
record of what it did, and bad readings, a used folder or another sensor are refused by name without
touching what is there."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="learn-object fits and fine-tunes with torch (the train extra)")

from synth.dataset import Dataset, generate, load_arrays  # noqa: E402
from synth.errors import ConfigError, ModelError  # noqa: E402
from synth.scene import load_scene  # noqa: E402
from synth.sensors.strips.physics import StripSensor  # noqa: E402
from tactile_learn.cli import main  # noqa: E402
from tactile_learn.learn_object import LearnConfig, _match_load, render_frames, write_rendered  # noqa: E402
from tactile_learn.learned_objects import learned_objects_in, readings_digest  # noqa: E402
from tactile_learn.methods import model_scene, resolve_method  # noqa: E402
from tactile_learn.object_tomography import ObjectTemplate, frame_loads  # noqa: E402

SCENE = load_scene("strips16")


def bar_object() -> ObjectTemplate:
    t = np.zeros((32, 32), np.float32)
    t[14:18, 6:26] = 1.0
    t[8:12, 20:24] = 2.0
    t /= t.sum()
    return ObjectTemplate(
        t, np.array([[30, 30], [20, 44]]), np.array([2.0, 6.0]), np.zeros(2, np.float32), 0.625, SCENE.digest
    )


@pytest.fixture(scope="module")
def object_frames(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """300 frames of an L-shaped object (a scene of the repository's shape library), readings only used."""
    out = tmp_path_factory.mktemp("ell") / "ell"
    generate(load_scene("strips16_objects_ell"), 300, 11, out)
    return out


def test_rendering_is_reproducible_by_seed(tmp_path: Path) -> None:
    a = write_rendered(bar_object(), SCENE, 300, 5, tmp_path / "a", vary=0.4, shard=128)
    b = write_rendered(bar_object(), SCENE, 300, 5, tmp_path / "b", vary=0.4, shard=128)
    c = write_rendered(bar_object(), SCENE, 300, 6, tmp_path / "c", vary=0.4, shard=128)
    ra, rb, rc = (Dataset(p.parent).arrays(["readings", "pressure"]) for p in (a, b, c))
    assert all(np.array_equal(ra[k], rb[k]) for k in ra)
    assert not np.array_equal(ra["readings"], rc["readings"])
    assert ra["readings"].shape == (300, 32) and ra["pressure"].shape == (300, 16, 16)
    assert np.isfinite(ra["pressure"]).all() and (ra["pressure"] >= 0).all()


def test_each_rendered_frame_carries_an_observed_load() -> None:
    sensor = StripSensor(SCENE.sensor)
    obj = bar_object()
    rng = np.random.default_rng(0)
    frames = render_frames(obj, SCENE.with_noise(False), 40, rng, vary=0.0)
    _, _, total = frame_loads(frames["readings"], sensor)
    nearest = np.abs(total[:, None] - obj.total_load[None, :]).min(1) / total
    assert nearest.max() < 1e-3
    # the bisection itself: any target load within the sensor's range is met
    fields = np.zeros((3, *sensor.field_shape))
    fields[:, 20:30, 20:40] = 1.0
    gains = np.ones((3, 32), np.float32)
    target = np.array([0.5, 2.0, 6.0])
    clean = sensor.forward(_match_load(fields, target, sensor, gains), gains=gains)["readings_clean"]
    assert np.allclose(frame_loads(clean, sensor)[2], target, rtol=1e-4)


def learn_args(frames: Path, out: Path) -> list[str]:
    args = ["learn-object", "--readings", str(frames), "--out", str(out), "--frames", "200"]
    return [*args, "--iterations", "1", "--n-train", "256", "--n-val", "64", "--epochs", "1", "--seed", "3"]


@pytest.fixture(scope="module")
def learned(object_frames: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One small learned object (one E/M round, one epoch), shared by the tests that read it."""
    out = tmp_path_factory.mktemp("learned") / "ell_object"
    assert main(learn_args(object_frames, out)) == 0
    return out


def test_learn_object_writes_a_specialist_and_its_record(object_frames: Path, learned: Path) -> None:
    out = learned
    record = json.loads((out / "object.json").read_text())
    assert record["frames"]["fitted"] == 200 and record["frames"]["used"] == 300
    assert record["command"].startswith("tactile-learn learn-object --readings")
    assert record["scene"] == "strips16_objects_ell" and 0 <= record["fit"]["residual_median"] < 1
    assert ObjectTemplate.load(out / "template.npz").template.shape == (128, 128)
    assert len(Dataset(out / "train")) == 256 and len(Dataset(out / "val")) == 64
    model = resolve_method("strips", str(out / "specialist.onnx"), SCENE, threads=1)
    readings = load_arrays(object_frames, ["readings"])["readings"][:8]
    pred = model.predict(readings)
    assert pred.shape == (8, 16, 16) and np.isfinite(pred).all()
    # a second run into the same folder is refused and leaves the first one's files as they were
    before = (out / "object.json").read_bytes()
    assert main(learn_args(object_frames, out)) == 2
    assert (out / "object.json").read_bytes() == before


def test_a_learned_objects_folder_is_a_method_that_answers_as_its_specialist(
    object_frames: Path, learned: Path
) -> None:
    readings = load_arrays(object_frames, ["readings"])["readings"][:16]
    by_folder = resolve_method("strips", str(learned), SCENE, threads=1).predict(readings)
    by_model = resolve_method("strips", str(learned / "specialist.onnx"), SCENE, threads=1).predict(readings)
    assert np.array_equal(by_folder, by_model)
    assert model_scene("strips", str(learned)) is not None
    assert learned_objects_in(learned.parent) == {"ell_object": learned / "specialist.onnx"}


@pytest.mark.parametrize(
    ("record", "message"),
    [
        ("{not json", "not readable JSON"),
        ('{"kind": "something else", "specialist": "specialist.onnx"}', "not a learned object's record"),
        ('{"kind": "tactile-learn learned object", "specialist": "../elsewhere.onnx"}', "must name a model file"),
        ('{"kind": "tactile-learn learned object", "specialist": "gone.onnx"}', "gone.onnx or the card"),
    ],
)
def test_a_broken_learned_object_is_refused_by_name(tmp_path: Path, record: str, message: str) -> None:
    folder = tmp_path / "broken"
    folder.mkdir()
    (folder / "object.json").write_text(record)
    with pytest.raises(ModelError, match=message):
        resolve_method("strips", str(folder), SCENE, threads=1)
    with pytest.raises(ModelError, match=message):
        learned_objects_in(tmp_path)
    with pytest.raises(ConfigError, match="holds no learned object"):
        learned_objects_in(folder)


def test_objects_builds_a_bundle_of_every_learned_object_in_a_folder(
    object_frames: Path, learned: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    other = tmp_path / "other"
    generate(load_scene("strips16_objects_ell").with_noise(True), 60, 12, other)
    other2 = tmp_path / "other2"
    generate(SCENE, 60, 13, other2)
    out = tmp_path / "bundle"
    argv = ["objects", "--learned", str(learned.parent), "--other", str(other), str(other2), "--out", str(out)]
    argv += ["--other-frames", "40", "--val-frames", "20", "--false-share", "0.2"]  # default 5000: capped
    assert main(argv) == 0
    bundle = json.loads((out / "bundle.json").read_text())
    assert bundle["objects"] == {"ell_object": "ell_object.onnx"} and "--learned" in bundle["command"]
    assert (out / "ell_object.onnx").read_bytes() == (learned / "specialist.onnx").read_bytes()
    # the router was fitted on the readings the object was learned from (300 frames: all but the 20 held out)
    assert bundle["trained_on"]["ell_object"] == {"data": str(object_frames), "frames": 280}
    # named twice (a folder and --learned), or nothing named: refused by name, nothing written
    again = ["objects", "--object", f"ell_object={learned}", "--learned", str(learned.parent)]
    assert main([*again, "--other", str(other), "--out", str(tmp_path / "twice")]) == 2
    assert "named twice" in capsys.readouterr().err and not (tmp_path / "twice").exists()
    assert main(["objects", "--other", str(other), "--out", str(tmp_path / "none")]) == 2
    assert "name the known objects" in capsys.readouterr().err


def test_a_bundle_refuses_a_learned_object_whose_readings_moved_or_changed(
    object_frames: Path, learned: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    record = json.loads((learned / "object.json").read_text())
    assert record["readings"]["path"] == str(object_frames) and record["readings"]["frames"] == 300
    assert record["readings"]["sha256"] == readings_digest(load_arrays(object_frames, ["readings"])["readings"])
    copy = tmp_path / "copy"
    shutil.copytree(learned, copy / "ell_object")
    edited = dict(record, readings=dict(record["readings"], path=str(tmp_path / "gone")))
    (copy / "ell_object" / "object.json").write_text(json.dumps(edited))
    argv = ["objects", "--learned", str(copy), "--other", str(object_frames), "--out", str(tmp_path / "b")]
    assert main(argv) == 2
    assert "cannot be read" in capsys.readouterr().err and not (tmp_path / "b").exists()
    other = load_arrays(object_frames, ["readings"])["readings"][::-1].copy()  # the same frames, another order
    np.savez(tmp_path / "other.npz", readings=other)
    edited["readings"]["path"] = str(tmp_path / "other.npz")
    (copy / "ell_object" / "object.json").write_text(json.dumps(edited))
    assert main(argv) == 2
    assert "checksum differs" in capsys.readouterr().err and not (tmp_path / "b").exists()
    del edited["readings"]
    (copy / "ell_object" / "object.json").write_text(json.dumps(edited))
    assert main(argv) == 2
    assert "names no readings" in capsys.readouterr().err


def test_bad_inputs_are_refused_by_name(
    object_frames: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    readings = load_arrays(object_frames, ["readings"])["readings"].copy()
    readings[3, 5] = np.nan
    np.savez(tmp_path / "nan.npz", readings=readings)
    out = tmp_path / "never"
    assert main(["learn-object", "--readings", str(tmp_path / "nan.npz"), "--out", str(out)]) == 2
    assert "readings" in capsys.readouterr().err and not out.exists()
    np.savez(tmp_path / "few.npz", readings=load_arrays(object_frames, ["readings"])["readings"][:50])
    assert main(["learn-object", "--readings", str(tmp_path / "few.npz"), "--out", str(out)]) == 2
    assert "at least 200" in capsys.readouterr().err and not out.exists()
    assert main(["learn-object", "--readings", str(object_frames), "--scene", "fsr6", "--out", str(out)]) == 2
    assert "strip arrays" in capsys.readouterr().err
    assert main(["learn-object", "--readings", str(object_frames), "--init", "no_such_model", "--out", str(out)]) == 2
    assert "no_such_model" in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("kwargs", [{"frames": 100}, {"n_train": 10}, {"vary": -0.1}, {"epochs": 0}, {"lr": 2.0}])
def test_out_of_range_settings_are_refused(kwargs: dict[str, float]) -> None:
    with pytest.raises(ConfigError):
        LearnConfig(**kwargs)  # type: ignore[arg-type]
