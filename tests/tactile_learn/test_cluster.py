"""Dask engine: shards simulated on cluster workers are the bytes of a local run."""

from __future__ import annotations

from pathlib import Path

import pytest

from synth.dataset import Dataset, generate
from synth.errors import ConfigError
from synth.scene import load_scene

distributed = pytest.importorskip("distributed", reason="the cluster extra (dask.distributed) is not installed")

from tactile_learn.cli import main  # noqa: E402
from tactile_learn.cluster import cluster_client, performance_report  # noqa: E402


def _shard_bytes(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.glob("shard-*.npy"))}


def test_cluster_generation_is_byte_identical_to_local(tmp_path: Path) -> None:
    scene = load_scene("strips5")
    generate(scene, 700, 11, tmp_path / "local", shard_size=200)
    report = tmp_path / "dask-report.html"
    with cluster_client(workers=2) as client, performance_report(report):
        generate(scene, 700, 11, tmp_path / "cluster", shard_size=200, executor=client.get_executor())
    local, remote = _shard_bytes(tmp_path / "local"), _shard_bytes(tmp_path / "cluster")
    assert len(local) == 4 * len(Dataset(tmp_path / "local").keys) and local == remote
    assert Dataset(tmp_path / "cluster").shards == Dataset(tmp_path / "local").shards  # same checksums
    assert report.stat().st_size > 1000  # the engine's own report of the run


def test_cli_generate_on_a_local_cluster_resumes(tmp_path: Path) -> None:
    out = tmp_path / "d"
    args = ["generate", "--scene", "strips5", "--n", "300", "--seed", "4", "--out", str(out), "--shard-size", "100"]
    assert main([*args, "--cluster", "--workers", "2", "--quiet"]) == 0
    first = _shard_bytes(out)
    (out / "shard-00001.readings.npy").write_bytes(b"broken")  # a damaged shard is simulated again
    assert main([*args, "--quiet"]) == 0
    assert _shard_bytes(out) == first


def test_unreachable_scheduler_is_a_clear_error() -> None:
    with pytest.raises(ConfigError, match="cannot reach"), cluster_client("tcp://127.0.0.1:9", timeout_s=1):
        pass
