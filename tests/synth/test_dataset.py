"""Datasets: deterministic for any worker count, resumable, corruption detected, never clobbered."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from synth.dataset import Dataset, generate, load_arrays
from synth.errors import DataError
from synth.scene import load_scene


def folder_bytes(path: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(path.iterdir()) if p.is_file()}


def test_same_seed_gives_identical_bytes_for_any_worker_count(tmp_path: Path) -> None:
    scene = load_scene("strips5")
    generate(scene, 3000, 11, tmp_path / "w1", shard_size=700, workers=1)
    generate(scene, 3000, 11, tmp_path / "w2", shard_size=700, workers=2)
    assert folder_bytes(tmp_path / "w1") == folder_bytes(tmp_path / "w2")
    generate(scene, 3000, 12, tmp_path / "other", shard_size=700)
    a = Dataset(tmp_path / "w1").array("readings")
    b = Dataset(tmp_path / "other").array("readings")
    assert not np.array_equal(a, b)


def test_manifest_records_what_was_made(tmp_path: Path) -> None:
    scene = load_scene("strips5")
    manifest_path = generate(scene, 100, 3, tmp_path / "d", shard_size=64)
    manifest = json.loads(manifest_path.read_text())
    assert manifest["seed"] == 3 and manifest["n"] == 100 and manifest["scene_digest"] == scene.digest
    assert manifest["arrays"]["readings"]["shape"] == [10]
    assert {"numpy", "scipy", "tactile_learn_synth"} <= set(manifest["versions"])
    assert [s["n"] for s in manifest["shards"]] == [64, 36]
    assert all(len(info["sha256"]) == 64 for s in manifest["shards"] for info in s["arrays"].values())
    data = Dataset(tmp_path / "d")
    assert len(data) == 100 and data.scene == scene
    assert isinstance(data.shard(0, "readings"), np.memmap)


def test_streaming_batches_cover_every_sample_once(tmp_path: Path) -> None:
    generate(load_scene("strips5"), 500, 4, tmp_path / "d", shard_size=128)
    data = Dataset(tmp_path / "d")
    everything = data.array("readings")
    seen = np.concatenate([b["readings"] for b in data.iter_batches(["readings"], 50, rng=np.random.default_rng(0))])
    assert len(seen) == 500
    order = np.lexsort(everything.T)
    order_seen = np.lexsort(seen.T)
    assert np.array_equal(everything[order], seen[order_seen])


class Interrupt(Exception):
    pass


def test_resume_after_interruption_matches_an_uninterrupted_run(tmp_path: Path) -> None:
    scene = load_scene("strips5")
    generate(scene, 2000, 5, tmp_path / "ref", shard_size=300)
    done = []

    def stop_after_two(n: int) -> None:
        done.append(n)
        if len(done) == 2:
            raise Interrupt

    with pytest.raises(Interrupt):
        generate(scene, 2000, 5, tmp_path / "run", shard_size=300, progress=stop_after_two)
    assert not (tmp_path / "run" / "manifest.json").exists()
    with pytest.raises(DataError, match="interrupted"):
        Dataset(tmp_path / "run")
    # debris a killed writer can leave: a temporary file, and a shard without its sidecar
    (tmp_path / "run" / ".shard-00004.readings.npy.tmp-999").write_bytes(b"half")
    (tmp_path / "run" / "shard-00005.readings.npy").write_bytes(b"garbage")
    generate(scene, 2000, 5, tmp_path / "run", shard_size=300)
    ref = folder_bytes(tmp_path / "ref")
    got = {k: v for k, v in folder_bytes(tmp_path / "run").items() if not k.startswith(".")}
    assert got == ref


def test_sigkilled_generation_resumes_to_identical_output(tmp_path: Path) -> None:
    code = (
        "import sys; from synth.scene import load_scene; from synth.dataset import generate; "
        "generate(load_scene('strips16'), 10000, 9, sys.argv[1], shard_size=500)"
    )
    reference = tmp_path / "ref"
    subprocess.run([sys.executable, "-c", code, str(reference)], check=True)
    killed = tmp_path / "killed"
    rng = np.random.default_rng(int(os.environ.get("TACTILE_KILL_SEED", "1")))
    proc = subprocess.Popen([sys.executable, "-c", code, str(killed)])
    deadline = time.monotonic() + 60
    target = int(rng.integers(2, 12))  # kill after a random number of finished shards
    while time.monotonic() < deadline and len(list(killed.glob("shard-*.json"))) < target and proc.poll() is None:
        time.sleep(0.005)
    os.kill(proc.pid, signal.SIGKILL)
    assert proc.wait() == -signal.SIGKILL, "the generation finished before it could be killed"
    assert not (killed / "manifest.json").exists()
    subprocess.run([sys.executable, "-c", code, str(killed)], check=True)
    assert folder_bytes(killed) == folder_bytes(reference)


def test_flipped_byte_is_detected_and_regenerated(tmp_path: Path) -> None:
    scene = load_scene("strips5")
    generate(scene, 400, 2, tmp_path / "d", shard_size=200)
    pristine = folder_bytes(tmp_path / "d")
    victim = tmp_path / "d" / "shard-00001.pressure.npy"
    blob = bytearray(victim.read_bytes())
    blob[-7] ^= 0x10
    victim.write_bytes(bytes(blob))
    with pytest.raises(DataError, match=r"shard-00001\.pressure\.npy: checksum mismatch"):
        Dataset(tmp_path / "d")
    Dataset(tmp_path / "d", verify=False)  # size check only: opens
    victim.write_bytes(bytes(blob[:-10]))
    with pytest.raises(DataError, match="bytes, manifest says"):
        Dataset(tmp_path / "d", verify=False)
    generate(scene, 400, 2, tmp_path / "d", shard_size=200)  # a rerun repairs the bad shard
    assert folder_bytes(tmp_path / "d") == pristine


def test_never_overwrites_another_dataset_without_being_told(tmp_path: Path) -> None:
    scene = load_scene("strips5")
    generate(scene, 100, 1, tmp_path / "d", shard_size=64)
    before = folder_bytes(tmp_path / "d")
    with pytest.raises(DataError, match="different dataset"):
        generate(scene, 100, 2, tmp_path / "d", shard_size=64)
    assert folder_bytes(tmp_path / "d") == before
    generate(scene, 100, 2, tmp_path / "d", shard_size=64, overwrite=True)
    assert Dataset(tmp_path / "d").seed == 2
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("precious")
    with pytest.raises(DataError, match="not a tactile-learn dataset"):
        generate(scene, 10, 1, foreign)
    generate(scene, 10, 1, foreign, overwrite=True)
    assert (foreign / "notes.txt").read_text() == "precious"  # only its own files are ever removed


def test_load_arrays_errors(tmp_path: Path) -> None:
    with pytest.raises(DataError, match="no such file"):
        load_arrays(tmp_path / "nope.npz")
    (tmp_path / "empty.npz").write_bytes(b"")
    with pytest.raises(DataError, match=r"not a readable \.npz"):
        load_arrays(tmp_path / "empty.npz")
    np.savez(tmp_path / "a.npz", readings=np.zeros((2, 10)))
    with pytest.raises(DataError, match="missing array"):
        load_arrays(tmp_path / "a.npz", ["readings", "pressure"])
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "manifest.json").write_text("{not json")
    with pytest.raises(DataError, match="corrupt manifest"):
        Dataset(tmp_path / "broken")
