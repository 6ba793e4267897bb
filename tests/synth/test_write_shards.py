"""synth.dataset.write_shards: arrays made outside a scene's simulator written as an ordinary dataset
(checksummed shards, the manifest last) that Dataset opens and verifies; shards that do not hold what
the manifest describes are refused before anything is written."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from synth.dataset import Dataset, write_shards
from synth.errors import DataError
from synth.scene import load_scene


def _shards() -> list[dict[str, np.ndarray]]:
    rng = np.random.default_rng(0)
    return [
        {
            "readings": rng.uniform(0, 1, (n, 32)).astype(np.float32),
            "pressure": rng.uniform(0, 9, (n, 16, 16)).astype(np.float32),
        }
        for n in (5, 3)
    ]


def test_the_folder_opens_verified_with_every_array_as_written(tmp_path: Path) -> None:
    shards = _shards()
    manifest = write_shards(tmp_path / "d", load_scene("strips16"), 7, shards, {"readings": "V", "pressure": "kPa"})
    data = Dataset(manifest.parent)
    assert len(data) == 8 and data.seed == 7 and data.scene.name == "strips16"
    np.testing.assert_array_equal(data.array("readings"), np.concatenate([s["readings"] for s in shards]))
    np.testing.assert_array_equal(data.array("pressure"), np.concatenate([s["pressure"] for s in shards]))
    assert data.manifest["arrays"]["pressure"] == {"shape": [16, 16], "dtype": "float32", "description": "kPa"}
    first = next((manifest.parent).glob("shard-*.readings.npy"))
    first.write_bytes(first.read_bytes()[:-4] + b"\0\0\0\1")  # a flipped byte: the checksum says so
    with pytest.raises(DataError, match="checksum"):
        Dataset(manifest.parent)


def test_shards_that_do_not_hold_the_described_arrays_are_refused(tmp_path: Path) -> None:
    shards = _shards()
    scene = load_scene("strips16")
    with pytest.raises(DataError, match="described arrays"):
        write_shards(tmp_path / "a", scene, 1, shards, {"readings": "V"})
    with pytest.raises(DataError, match="described arrays"):
        write_shards(
            tmp_path / "b",
            scene,
            1,
            [shards[0], {"readings": shards[1]["readings"]}],
            {"readings": "V", "pressure": "kPa"},
        )
    with pytest.raises(DataError, match="no shards"):
        write_shards(tmp_path / "c", scene, 1, [], {})
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
