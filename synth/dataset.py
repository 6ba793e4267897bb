"""Sharded, seeded, resumable datasets of simulated samples.

Layout of a dataset folder::

    generation.json              what was asked for (scene, seed, n, shard size): written first
    shard-00000.readings.npy     one memory-mappable .npy per output and shard
    shard-00000.json             that shard's sizes and SHA-256 checksums: written after its arrays
    ...
    manifest.json                everything above plus versions: written atomically, last

Shard ``i`` is simulated with ``numpy.random.SeedSequence(seed, spawn_key=(i,))`` in fixed chunks, so
its bytes depend only on (scene, seed, shard size, i): any number of workers, and any interruption
followed by a rerun, give identical files. A rerun keeps every shard whose sidecar verifies and
simulates the rest. A flipped byte anywhere is caught by the checksums when the dataset is opened.
"""

from __future__ import annotations

import json
import math
import os
import platform
import sys
import zipfile
import zlib
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from synth import __version__
from synth.errors import ConfigError, DataError
from synth.io import atomic_save_npy, atomic_write_json, sha256_file
from synth.scene import Scene, parse_scene
from synth.sensors import sensor_module

__all__ = ["FORMAT_VERSION", "Dataset", "generate", "load_arrays", "simulate_shard", "stream", "write_shards"]

FORMAT_VERSION = 1
#: samples simulated per call inside a shard; fixed so that the random stream never depends on it
CHUNK = 1024
GENERATION = "generation.json"
MANIFEST = "manifest.json"

ProgressCallback = Callable[[int], None]


def _shard_name(index: int) -> str:
    return f"shard-{index:05d}"


def _request(scene: Scene, n: int, seed: int, shard_size: int) -> dict[str, Any]:
    simulator = sensor_module(scene.task).make_simulator(scene)
    specs = simulator.output_specs()
    return {
        "format": FORMAT_VERSION,
        "scene": scene.to_dict(),
        "scene_digest": scene.digest,
        "seed": seed,
        "n": n,
        "shard_size": shard_size,
        "chunk": CHUNK,
        "arrays": {
            k: {"shape": list(s.shape), "dtype": s.dtype, "description": s.description} for k, s in specs.items()
        },
    }


def simulate_shard(scene: Scene, seed: int, index: int, size: int, pixels: int | None = None) -> dict[str, np.ndarray]:
    """Arrays of shard ``index`` (``size`` samples), deterministic in (scene, seed, index, size);
    ``pixels``: a thermal scene's touches with only that many random pixels read (training's
    share: :mod:`synth.sensors.thermal.subset`)."""
    module = sensor_module(scene.task)
    if pixels is None:
        simulator = module.make_simulator(scene)
    elif scene.task == "thermal":
        simulator = module.make_simulator(scene, pixels=pixels)
    else:
        raise ConfigError(f"pixels: only thermal scenes read a subset of pixels ({scene.name!r} is {scene.task!r})")
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(index,)))
    parts: list[dict[str, np.ndarray]] = []
    for start in range(0, size, CHUNK):
        parts.append(simulator.simulate(min(CHUNK, size - start), rng))
    if not parts:
        return {k: np.zeros((0, *s.shape), dtype=s.dtype) for k, s in simulator.output_specs().items()}
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def stream(scene: Scene, seed: int, shard_size: int = 8192, start: int = 0) -> Iterator[dict[str, np.ndarray]]:
    """Endless shards of fresh samples, never written: shard ``start``, ``start + 1``, ... of
    ``seed`` (each :func:`simulate_shard`), so the first ``k`` are, byte for byte, the shards of
    ``generate(scene, k * shard_size, seed, out, shard_size=shard_size)``."""
    if isinstance(shard_size, bool) or not isinstance(shard_size, int) or shard_size < 1:
        raise ConfigError(f"shard_size: expected a positive integer, got {shard_size!r}")
    index = start
    while True:
        yield simulate_shard(scene, seed, index, shard_size)
        index += 1


def _write_shard(folder: Path, scene: Scene, seed: int, index: int, size: int) -> dict[str, Any]:
    return _store_shard(folder, index, size, simulate_shard(scene, seed, index, size))


def _store_shard(folder: Path, index: int, size: int, arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    """Write shard ``index``'s arrays, then its sidecar (sizes and checksums): the sidecar last, so a
    shard whose sidecar verifies is complete."""
    name = _shard_name(index)
    files = {}
    for key, array in arrays.items():
        path = folder / f"{name}.{key}.npy"
        atomic_save_npy(path, array)
        files[key] = {"file": path.name, "sha256": sha256_file(path), "bytes": path.stat().st_size}
    record = {"index": index, "n": size, "arrays": files}
    atomic_write_json(folder / f"{name}.json", record)
    return record


def _shard_ok(folder: Path, index: int, size: int, keys: Sequence[str]) -> dict[str, Any] | None:
    """The shard's sidecar if it and every file it lists verify, else ``None`` (to be rewritten)."""
    sidecar = folder / f"{_shard_name(index)}.json"
    try:
        record = json.loads(sidecar.read_text())
        if record["n"] != size or sorted(record["arrays"]) != sorted(keys):
            return None
        for info in record["arrays"].values():
            path = folder / info["file"]
            if path.stat().st_size != info["bytes"] or sha256_file(path) != info["sha256"]:
                return None
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return dict(record)


def _owned_files(folder: Path) -> list[Path]:
    return [
        p
        for p in folder.iterdir()
        if p.name in (GENERATION, MANIFEST) or (p.name.startswith(("shard-", ".shard-")) and p.is_file())
    ]


def _prepare_folder(folder: Path, request: dict[str, Any], overwrite: bool) -> None:
    if folder.exists() and not folder.is_dir():
        raise DataError(f"{folder} is a file, not a dataset folder; choose another --out")
    folder.mkdir(parents=True, exist_ok=True)
    existing = folder / GENERATION
    if existing.exists():
        try:
            previous = json.loads(existing.read_text())
        except ValueError:
            previous = None
        if previous == request:
            return  # same request: resume
        if not overwrite:
            raise DataError(
                f"{folder} holds a different dataset (scene, seed, n or shard size differ); "
                "pass --overwrite to replace it, or choose another --out"
            )
    elif any(folder.iterdir()) and not overwrite:
        raise DataError(
            f"{folder} is not empty and is not a tactile-learn dataset; pass --overwrite or choose another --out"
        )
    if overwrite:
        for path in _owned_files(folder):
            path.unlink()
    atomic_write_json(existing, request)


def generate(
    scene: Scene,
    n: int,
    seed: int,
    out: str | Path,
    *,
    shard_size: int = 8192,
    workers: int = 1,
    overwrite: bool = False,
    progress: ProgressCallback | None = None,
    executor: Executor | None = None,
) -> Path:
    """Simulate ``n`` samples of ``scene`` into the folder ``out`` and return its manifest path.

    Resumes an interrupted run with the same arguments (finished shards are kept); refuses to
    write over a different dataset unless ``overwrite``. ``progress`` is called with the number of
    samples each finished shard adds.

    ``executor`` (any :class:`concurrent.futures.Executor`, e.g. a Dask cluster's
    ``client.get_executor()``) simulates the shards elsewhere: each worker returns its shard's
    arrays and this process writes them, so the workers need no access to ``out`` and the bytes are
    those of a local run (a shard depends only on scene, seed, shard size and index).
    """
    if isinstance(n, bool) or not isinstance(n, int) or n < 0:
        raise ConfigError(f"n: expected a non-negative integer, got {n!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError(f"seed: expected a non-negative integer, got {seed!r}")
    if isinstance(shard_size, bool) or not isinstance(shard_size, int) or shard_size < 1:
        raise ConfigError(f"shard_size: expected a positive integer, got {shard_size!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers: expected a positive integer, got {workers!r}")
    folder = Path(out)
    request = _request(scene, n, seed, shard_size)
    _prepare_folder(folder, request, overwrite)
    sizes = [min(shard_size, n - i * shard_size) for i in range(math.ceil(n / shard_size))]
    keys = list(request["arrays"])
    records: dict[int, dict[str, Any]] = {}
    todo = []
    for index, size in enumerate(sizes):
        record = _shard_ok(folder, index, size, keys)
        if record is None:
            todo.append(index)
        else:
            records[index] = record
            if progress:
                progress(size)
    if todo and executor is not None:
        futures = {executor.submit(simulate_shard, scene, seed, i, sizes[i]): i for i in todo}
        for future in as_completed(futures):
            index = futures[future]
            records[index] = _store_shard(folder, index, sizes[index], future.result())
            if progress:
                progress(sizes[index])
    elif todo and workers > 1:
        # spawn, not fork: a forked BLAS/OpenMP pool can deadlock, and spawn behaves alike on every OS
        with ProcessPoolExecutor(max_workers=min(workers, len(todo)), mp_context=get_context("spawn")) as pool:
            futures = {pool.submit(_write_shard, folder, scene, seed, i, sizes[i]): i for i in todo}
            for future in as_completed(futures):
                records[futures[future]] = future.result()
                if progress:
                    progress(sizes[futures[future]])
    else:
        for index in todo:
            records[index] = _write_shard(folder, scene, seed, index, sizes[index])
            if progress:
                progress(sizes[index])
    manifest = dict(request)
    manifest["shards"] = [records[i] for i in range(len(sizes))]
    manifest["versions"] = _versions()
    atomic_write_json(folder / MANIFEST, manifest)
    return folder / MANIFEST


def write_shards(
    out: str | Path,
    scene: Scene,
    seed: int,
    shards: Sequence[dict[str, np.ndarray]],
    descriptions: dict[str, str],
) -> Path:
    """A dataset folder of arrays made elsewhere (e.g. stimuli no scene draws, pushed through the
    scene's sensor model): each of ``shards`` written with its checksums, then the manifest (the
    scene, the seed that made them, every array's per-sample shape, dtype and ``descriptions``
    entry), last and atomically, as :func:`generate` writes one. Returns the manifest's path."""
    if not shards:
        raise DataError(f"{out}: no shards to write")
    keys = list(shards[0])
    if set(keys) != set(descriptions) or any(list(shard) != keys for shard in shards):
        raise DataError(f"{out}: every shard must hold the described arrays ({', '.join(sorted(descriptions))})")
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    records = [_store_shard(folder, i, len(shard[keys[0]]), shard) for i, shard in enumerate(shards)]
    first = shards[0]
    manifest = {
        "format": FORMAT_VERSION,
        "scene": scene.to_dict(),
        "scene_digest": scene.digest,
        "seed": seed,
        "n": sum(int(r["n"]) for r in records),
        "shard_size": int(records[0]["n"]),
        "chunk": int(records[0]["n"]),
        "arrays": {
            k: {"shape": list(first[k].shape[1:]), "dtype": str(first[k].dtype), "description": descriptions[k]}
            for k in keys
        },
        "shards": records,
        "versions": _versions(),
    }
    atomic_write_json(folder / MANIFEST, manifest)
    return folder / MANIFEST


def _versions() -> dict[str, str]:
    import scipy

    return {
        "tactile_learn_synth": __version__,
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "python": platform.python_version(),
        "platform": sys.platform,
    }


class Dataset:
    """A generated dataset folder, opened read-only with memory-mapped shards.

    Opening checks the manifest and, with ``verify=True`` (the default), every shard's SHA-256, so
    a truncated or corrupted file is reported by name instead of feeding wrong numbers downstream.
    """

    def __init__(self, path: str | Path, *, verify: bool = True) -> None:
        self.path = Path(path)
        manifest_path = self.path / MANIFEST
        if not self.path.is_dir():
            raise DataError(f"{self.path}: no such dataset folder")
        if not manifest_path.is_file():
            if (self.path / GENERATION).exists():
                hint = " (generation was interrupted: rerun the same generate command to finish it)"
            else:  # e.g. a recordings folder where a dataset or an .npz is read
                hint = " (not a dataset folder: tactile-learn generate writes those; or give an .npz file)"
            raise DataError(f"{self.path}: no manifest.json{hint}")
        try:
            self.manifest: dict[str, Any] = json.loads(manifest_path.read_text())
        except ValueError as exc:
            raise DataError(f"{manifest_path}: corrupt manifest ({exc})") from None
        if self.manifest.get("format") != FORMAT_VERSION:
            raise DataError(f"{manifest_path}: dataset format {self.manifest.get('format')!r} is not {FORMAT_VERSION}")
        try:
            self.scene: Scene = parse_scene(self.manifest["scene"], str(manifest_path))
            self.shards: list[dict[str, Any]] = list(self.manifest["shards"])
            self.keys: list[str] = list(self.manifest["arrays"])
        except KeyError as exc:
            raise DataError(f"{manifest_path}: manifest lacks {exc}") from None
        for shard in self.shards:
            for info in shard["arrays"].values():
                file = self.path / info["file"]
                if not file.is_file():
                    raise DataError(f"{file}: shard file is missing")
                if file.stat().st_size != info["bytes"]:
                    raise DataError(
                        f"{file}: shard file has {file.stat().st_size} bytes, manifest says {info['bytes']}"
                    )
                if verify and sha256_file(file) != info["sha256"]:
                    raise DataError(f"{file}: checksum mismatch, the shard is corrupt (regenerate it)")
        self._maps: dict[tuple[int, str], np.ndarray] = {}

    def __len__(self) -> int:
        return int(self.manifest["n"])

    @property
    def seed(self) -> int:
        return int(self.manifest["seed"])

    def shard(self, index: int, key: str) -> np.ndarray:
        """Memory-mapped (read-only) array ``key`` of shard ``index``."""
        if key not in self.keys:
            raise DataError(f"{self.path}: dataset has no array {key!r} (it has: {', '.join(self.keys)})")
        cached = self._maps.get((index, key))
        if cached is None:
            file = self.path / self.shards[index]["arrays"][key]["file"]
            try:
                cached = np.load(file, mmap_mode="r", allow_pickle=False)
            except ValueError as exc:
                raise DataError(f"{file}: unreadable shard ({exc})") from None
            expected = (self.shards[index]["n"], *self.manifest["arrays"][key]["shape"])
            if cached.shape != expected:
                raise DataError(f"{file}: shape {cached.shape} does not match the manifest's {expected}")
            self._maps[(index, key)] = cached
        return cached

    def array(self, key: str, limit: int | None = None) -> np.ndarray:
        """All of ``key`` (or its first ``limit`` samples) in memory, concatenated over shards."""
        if limit is not None and (not hasattr(limit, "__index__") or limit < 0):  # [:-1] would drop one silently
            raise ConfigError(f"limit: expected a non-negative number of samples, got {limit!r}")
        parts = []
        remaining = len(self) if limit is None else min(limit, len(self))
        for index in range(len(self.shards)):
            if remaining <= 0:
                break
            part = self.shard(index, key)[:remaining]
            parts.append(np.asarray(part))
            remaining -= len(part)
        if not parts:
            spec = self.manifest["arrays"][key]
            return np.zeros((0, *spec["shape"]), dtype=spec["dtype"])
        return np.concatenate(parts)

    def arrays(self, keys: Sequence[str] | None = None, limit: int | None = None) -> dict[str, np.ndarray]:
        return {k: self.array(k, limit) for k in (keys or self.keys)}

    def iter_batches(
        self,
        keys: Sequence[str],
        batch_size: int,
        rng: np.random.Generator | None = None,
        drop_last: bool = False,
    ) -> Iterator[dict[str, np.ndarray]]:
        """Stream batches one shard at a time (at most one shard in memory).

        With ``rng`` the shard order and the samples within each shard are shuffled.
        """
        order = np.arange(len(self.shards))
        if rng is not None:
            rng.shuffle(order)
        for index in order:
            n = int(self.shards[index]["n"])
            perm = rng.permutation(n) if rng is not None else np.arange(n)
            maps = {k: self.shard(int(index), k) for k in keys}
            for start in range(0, n, batch_size):
                sel = perm[start : start + batch_size]
                if drop_last and len(sel) < batch_size:
                    break
                if rng is not None:
                    sel = np.sort(sel)  # sorted gathers read memory maps sequentially
                yield {k: np.asarray(m[sel]) for k, m in maps.items()}


#: first bytes of an .npz (a zip archive) and of a single .npy array
ZIP_MAGIC = b"PK"
NPY_MAGIC = b"\x93NUMPY"


def load_arrays(path: str | Path, keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """Arrays from a generated dataset folder or a ``.npz`` file (e.g. a user's own recordings)."""
    source = Path(path)
    if source.is_dir():
        return Dataset(source).arrays(keys)
    if not source.is_file():
        raise DataError(f"{source}: no such file or dataset folder")
    _check_npz_magic(source)
    try:
        with np.load(source, allow_pickle=False) as data:
            wanted = list(data.files) if keys is None else list(keys)
            missing = [k for k in wanted if k not in data.files]
            if missing:
                raise DataError(f"{source}: missing array(s) {', '.join(missing)} (it has: {', '.join(data.files)})")
            return {k: np.asarray(data[k]) for k in wanted}
    except DataError:
        raise
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        # a truncated or damaged archive fails in zipfile (BadZipFile, a CRC or zlib error) or in numpy
        raise DataError(f"{source}: not a readable .npz file: truncated or corrupt ({exc})") from None


def _check_npz_magic(source: Path) -> None:
    """Refuse what is not an .npz archive by its first bytes, before numpy guesses (numpy reads any
    other file as a pickle and says so, which misleads: the user meant arrays)."""
    with source.open("rb") as file:
        head = file.read(len(NPY_MAGIC))
    if not head:
        raise DataError(f"{source}: not a readable .npz file: it is empty (expected named arrays: numpy.savez)")
    if head.startswith(NPY_MAGIC):
        raise DataError(
            f"{source}: not a readable .npz file: it is a single .npy array; save the arrays by name "
            "(numpy.savez(path, readings=...))"
        )
    if not head.startswith(ZIP_MAGIC):
        raise DataError(f"{source}: not a readable .npz file: not a zip archive of named arrays (numpy.savez)")


def default_workers() -> int:
    return max(1, min(4, os.cpu_count() or 1))
