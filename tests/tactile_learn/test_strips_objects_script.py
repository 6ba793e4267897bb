"""scripts/strips_objects.py: every family of the unseen rounds 1..K as training frames, at seeds no
evaluation draws, and the training command and router that use them."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from synth.dataset import load_arrays
from synth.suite import load_suite, suite_frames
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_objects as objects
import strips_prior_router


def test_rounds_name_their_suites_and_every_family_has_its_own_seed(tmp_path: Path) -> None:
    assert objects.round_suite(1) == "strips16_unseen" and objects.round_suite(8) == "strips16_unseen8"
    with pytest.raises(ValueError, match="round"):
        objects.round_suite(0)
    listed = objects.object_folders(3, tmp_path)
    assert len(listed) == sum(len(load_suite(objects.round_suite(k)).families) for k in (1, 2, 3))
    seeds = [objects.SEED + 100 * k + i for k, i, *_ in listed]
    assert len(set(seeds)) == len(seeds) and not {5151, 6262} & set(seeds)
    assert len({folder for *_, folder in listed}) == len(listed)
    # rounds 1..K-1 are a prefix of rounds 1..K: the two experts share their frames
    assert objects.object_folders(2, tmp_path) == listed[: len(objects.object_folders(2, tmp_path))]


def test_written_frames_are_the_family_at_the_declared_seed_and_a_rerun_keeps_them(tmp_path: Path) -> None:
    objects.write_data(1, tmp_path, n=3, log=lambda *a: None)
    k, i, family, folder = objects.object_folders(1, tmp_path)[4]
    manifest = json.loads((folder / "manifest.json").read_text())
    assert manifest["seed"] == objects.SEED + 100 * k + i and manifest["n"] == 3
    written = load_arrays(folder, ["readings"])["readings"]
    other = suite_frames(load_suite("strips16_unseen"), 3, 5151)[family]
    assert written.shape == other["readings"].shape and not np.array_equal(written, other["readings"])
    before = (folder / "manifest.json").stat().st_mtime_ns
    objects.write_data(1, tmp_path, n=3, log=lambda *a: None)  # resumes: nothing rewritten
    assert (folder / "manifest.json").stat().st_mtime_ns == before


def test_the_plan_trains_on_the_base_mixture_and_every_object(tmp_path: Path) -> None:
    command = objects.plan(2, tmp_path, Path("runs/x"))
    for folder in [*objects.BASE_DATA, *(str(f) for *_, f in objects.object_folders(2, tmp_path))]:
        assert f" {folder} " in command
    assert "--init runs/arr/model.pt" in command and "--threads 1" in command and "--out runs/x" in command
    assert "--teacher" not in command
    taught = objects.plan(2, tmp_path, Path("runs/x"), teacher=True)
    assert taught.startswith(command) and taught.endswith(
        " --teacher models/strips16.pt --teacher-data data/pf-wide-train data/pf-spheres-train"
    )
    assert set(objects.TAUGHT) <= set(objects.BASE_DATA)  # taught frames are frames of the mixture


def test_the_router_adds_the_objects_to_the_generic_side(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    seen: dict[str, object] = {}

    def fake_train(out: Path, generic: dict[str, int], models: dict[str, str]) -> dict[str, object]:
        seen.update(out=out, generic=generic, models=models)
        return {"held_out_accuracy": 1.0, "threshold": 0.5}

    monkeypatch.setattr(strips_prior_router, "train", fake_train)
    objects.train_router(1, tmp_path, tmp_path / "r", "runs/objects7/candidate.onnx")
    generic = seen["generic"]
    assert isinstance(generic, dict)
    assert set(strips_prior_router.GENERIC) <= set(generic) and "data/arrangements-train" in generic
    assert sum(1 for f in generic if f.startswith(str(tmp_path))) == len(load_suite("strips16_unseen").families)
    assert seen["models"] == {"library": "models/strips16.onnx", "generic": "runs/objects7/candidate.onnx"}


def test_the_two_sphere_router_keeps_only_two_spheres_on_the_library_side(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    seen: dict[str, object] = {}

    def fake_train(
        out: Path, generic: dict[str, int], models: dict[str, str], library: dict[str, int], threshold: float
    ) -> dict[str, object]:
        seen.update(generic=generic, models=models, library=library, threshold=threshold)
        return {"held_out_accuracy": 1.0, "threshold": threshold}

    monkeypatch.setattr(strips_prior_router, "train", fake_train)
    objects.train_sphere_router(2, tmp_path, tmp_path / "r", "runs/objects10c/candidate.onnx", 0.3)
    assert seen["threshold"] == 0.3
    library, generic = seen["library"], seen["generic"]
    assert isinstance(library, dict) and isinstance(generic, dict)
    assert library == {"data/pf-spheres-train": 20000}
    # the shape library's own scenes are generic now: only two spheres stay with the library network
    assert {"data/pf-wide-train", "data/shapes-mixed-train"} <= set(generic) and not set(library) & set(generic)
    families = objects.object_folders(2, tmp_path)
    assert [generic[str(f)] for *_, f in families] == [objects.SPHERE_ROUTER_FRAMES_PER_FAMILY] * len(families)
    # with the 121 families of rounds 1-10, the two sides are drawn to about equal size (20,000 / 20,025)
    ten = len(objects.object_folders(10, tmp_path)) * objects.SPHERE_ROUTER_FRAMES_PER_FAMILY
    assert abs(sum(library.values()) - sum(objects.SPHERE_ROUTER_GENERIC.values()) - ten) <= 100
    assert seen["models"] == {"library": "models/strips16.onnx", "generic": "runs/objects10c/candidate.onnx"}


def test_a_router_threshold_outside_0_1_is_refused(tmp_path: Path) -> None:
    for bad in (0.0, 1.0, -0.2, float("nan")):
        with pytest.raises(ValueError, match="threshold"):
            strips_prior_router.train(tmp_path, threshold=bad)
