"""Training on touches simulated as they are needed: a scene instead of a dataset folder.

A :class:`TouchStream` stands where :class:`synth.dataset.Dataset` stands in the training loop
(``tactile-learn train --scene NAME --stream N``). Its samples are shards of
:func:`synth.dataset.simulate_shard`: shard ``i`` of seed ``S`` with ``shard_size`` samples is, byte
for byte, shard ``i`` of ``generate --seed S --shard-size shard_size``. Nothing is written.

Epochs and shuffling. An epoch is ``n`` samples in ``ceil(n / shard_size)`` shards. With
``fresh=True`` (the default) epoch ``e`` (1, 2, ...) draws new shards, ``(e - 1) k ... e k - 1``,
so no sample is seen twice; with ``fresh=False`` every epoch reuses shards ``0 ... k - 1``, and
training is exactly training on the dataset ``generate --n n --seed S`` (same batches, same weights
for the same ``--seed``). Either way an epoch's shard order and the order within each shard are
shuffled with the epoch's generator, as :meth:`~synth.dataset.Dataset.iter_batches` does. The next
shard is simulated in a background thread while the current one trains (numpy and torch release
the GIL in their loops).

Only what training reads. The thermal task trains on a few random pixels of every touch
(``tactile_learn.tasks.thermal``: 4 of a 4 x 4 array); ``pixels=4`` simulates just those
(:mod:`synth.sensors.thermal.subset`: the scene's touches, 4 random pixels each, about a quarter of
the work), and the pixel curves trained on have the full array's distribution. Such a stream is
no longer a dataset's shards byte for byte (its pixels are chosen before the noise is drawn).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np

from synth.dataset import simulate_shard
from synth.errors import ConfigError, DataError
from synth.scene import Scene
from synth.sensors import sensor_module

__all__ = ["TouchStream"]


class TouchStream:
    """``n`` samples per epoch of ``scene``, simulated from ``seed`` (see the module docstring)."""

    def __init__(
        self,
        scene: Scene,
        n: int,
        seed: int,
        shard_size: int = 8192,
        fresh: bool = True,
        pixels: int | None = None,
    ) -> None:
        for name, value, low in (("n", n, 1), ("seed", seed, 0), ("shard_size", shard_size, 1)):
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ConfigError(f"stream {name}: expected an integer >= {low}, got {value!r}")
        self.scene = scene
        self.n = n
        self._seed = seed
        self.shard_size = shard_size
        self.fresh = fresh
        self.pixels = pixels
        if pixels is not None:  # refused here, not in the first shard's worker: the scene and the count
            simulate_shard(scene, seed, 0, 0, pixels)
        self.sizes = [min(shard_size, n - i * shard_size) for i in range(math.ceil(n / shard_size))]
        self.shards: list[dict[str, Any]] = [{"n": size} for size in self.sizes]
        self.keys: list[str] = list(sensor_module(scene.task).make_simulator(scene).output_specs())
        self._last: tuple[int, dict[str, np.ndarray]] | None = None  # statistics, then epoch 1: one simulation

    def __len__(self) -> int:
        return self.n

    @property
    def seed(self) -> int:
        return self._seed

    def describe(self) -> dict[str, Any]:
        """What a run records of its training data."""
        return {
            "stream": self.scene.name,
            "seed": self._seed,
            "n": self.n,
            "shard_size": self.shard_size,
            "fresh": self.fresh,
            **({"pixels_per_touch": self.pixels} if self.pixels is not None else {}),
        }

    def _shard(self, index: int) -> dict[str, np.ndarray]:
        last = self._last
        if last is not None and last[0] == index:
            return last[1]
        arrays = simulate_shard(self.scene, self._seed, index, self.sizes[index % len(self.sizes)], self.pixels)
        self._last = (index, arrays)
        return arrays

    def _index(self, position: int, epoch: int) -> int:
        """Shard index of the epoch's ``position``-th shard (``fresh``: new shards every epoch)."""
        return position + (epoch - 1) * len(self.sizes) if self.fresh else position

    def _check(self, keys: Sequence[str]) -> None:
        missing = [k for k in keys if k not in self.keys]
        if missing:
            raise DataError(f"scene {self.scene.name!r} does not simulate {', '.join(missing)}")

    def arrays(self, keys: Sequence[str] | None = None, limit: int | None = None) -> dict[str, np.ndarray]:
        """The first ``limit`` samples (default: one epoch's worth) of the first epoch."""
        wanted = list(keys or self.keys)
        self._check(wanted)
        remaining = self.n if limit is None else min(limit, self.n)
        parts: list[dict[str, np.ndarray]] = []
        position = 0
        while remaining > 0:
            shard = self._shard(self._index(position, 1))
            parts.append({k: shard[k][:remaining] for k in wanted})
            remaining -= len(parts[-1][wanted[0]])
            position += 1
        return {k: np.concatenate([p[k] for p in parts]) for k in wanted}

    def epoch_batches(
        self,
        epoch: int,
        keys: Sequence[str],
        batch_size: int,
        rng: np.random.Generator,
        drop_last: bool = False,
    ) -> Iterator[dict[str, np.ndarray]]:
        """Batches of epoch ``epoch`` (1, 2, ...), shuffled like the dataset's
        :meth:`~synth.dataset.Dataset.iter_batches` with the same ``rng`` calls."""
        self._check(keys)
        order = np.arange(len(self.sizes))
        rng.shuffle(order)
        pool = ThreadPoolExecutor(max_workers=1)
        try:
            pending: Future[dict[str, np.ndarray]] = pool.submit(self._shard, self._index(int(order[0]), epoch))
            for k, position in enumerate(order):
                shard = pending.result()
                if k + 1 < len(order):  # the next shard simulates while this one trains
                    pending = pool.submit(self._shard, self._index(int(order[k + 1]), epoch))
                n = self.sizes[int(position)]
                perm = rng.permutation(n)
                for start in range(0, n, batch_size):
                    sel = perm[start : start + batch_size]
                    if drop_last and len(sel) < batch_size:
                        break
                    sel = np.sort(sel)  # as the dataset does (it reads its memory maps in order)
                    yield {key: shard[key][sel] for key in keys}
        finally:  # a loop that stops early (max_batches) does not wait for a shard it will not use
            pool.shutdown(wait=False, cancel_futures=True)
