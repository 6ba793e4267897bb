"""Several generated datasets of one sensor read as one training set.

A general model learns from a mixture (e.g. the whole shape library and a two-sphere set); rather
than generating the mixture again, ``train`` reads the folders side by side. Every folder must
describe the same sensor (``Task.same_sensor``: the stimuli may differ); an epoch visits every
shard of every folder once, in an order shuffled across folders, so batches of each kind alternate
through the epoch instead of following one another folder by folder.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np

from synth.dataset import Dataset
from synth.errors import DataError
from synth.scene import Scene

__all__ = ["TrainingSet"]


class TrainingSet:
    """The datasets in ``paths`` (the first one's scene is the training scene)."""

    def __init__(self, paths: Sequence[str], same_sensor: Any) -> None:
        if not paths:
            raise DataError("--data: no training dataset given")
        self.parts = [Dataset(p) for p in paths]
        self.scene: Scene = self.parts[0].scene
        for path, part in zip(paths[1:], self.parts[1:], strict=True):
            if not same_sensor(self.scene, part.scene):
                raise DataError(
                    f"{path}: scene {part.scene.name!r} describes another sensor than {paths[0]} "
                    f"({self.scene.name!r}); a training set's folders must share the sensor"
                )
        self.keys: list[str] = [k for k in self.parts[0].keys if all(k in p.keys for p in self.parts[1:])]
        self.shards: list[dict[str, Any]] = [s for p in self.parts for s in p.shards]

    def __len__(self) -> int:
        return sum(len(p) for p in self.parts)

    @property
    def seeds(self) -> list[int]:
        return [p.seed for p in self.parts]

    def arrays(self, keys: Sequence[str], limit: int | None = None) -> dict[str, np.ndarray]:
        """``keys`` of every folder, each folder's share of ``limit`` in proportion to its size."""
        if len(self.parts) == 1:
            return self.parts[0].arrays(keys, limit)
        total = len(self)
        shares = [None if limit is None else max(1, round(limit * len(p) / total)) for p in self.parts]
        got = [p.arrays(keys, share) for p, share in zip(self.parts, shares, strict=True)]
        return {k: np.concatenate([g[k] for g in got]) for k in keys}

    def iter_batches(
        self,
        keys: Sequence[str],
        batch_size: int,
        rng: np.random.Generator,
        drop_last: bool = True,
        part_key: str | None = None,
    ) -> Iterator[dict[str, np.ndarray]]:
        """Shuffled batches, one shard in memory at a time, shards of all folders interleaved; with
        ``part_key``, each batch also holds every frame's folder index under that key (the random
        stream is the same with or without it)."""
        if len(self.parts) == 1:  # exactly the single dataset's stream: runs from before stay reproducible
            for batch in self.parts[0].iter_batches(keys, batch_size, rng=rng, drop_last=drop_last):
                if part_key is not None:
                    batch[part_key] = np.zeros(len(next(iter(batch.values()))), dtype=np.int64)
                yield batch
            return
        order = [(i, s) for i, p in enumerate(self.parts) for s in range(len(p.shards))]
        for k in rng.permutation(len(order)):
            part_index, shard_index = order[k]
            part = self.parts[part_index]
            n = int(part.shards[shard_index]["n"])
            perm = rng.permutation(n)
            maps = {key: part.shard(shard_index, key) for key in keys}
            for start in range(0, n, batch_size):
                sel = perm[start : start + batch_size]
                if drop_last and len(sel) < batch_size:
                    break
                sel = np.sort(sel)  # sorted gathers read memory maps sequentially
                batch = {key: np.asarray(m[sel]) for key, m in maps.items()}
                if part_key is not None:
                    batch[part_key] = np.full(len(sel), part_index, dtype=np.int64)
                yield batch
