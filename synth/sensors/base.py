"""The simulator interface every sensor model implements."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass(frozen=True)
class ArraySpec:
    """Shape of one sample of an output (without the batch axis) and its dtype."""

    shape: tuple[int, ...]
    dtype: str
    description: str = ""


class Simulator(Protocol):
    """Draws stimuli from a scene's distributions and computes the requested outputs.

    ``simulate`` is pure given ``rng``: the same generator state gives the same arrays. Outputs are
    batch-first numpy arrays whose per-sample shape and dtype match ``output_specs()``.
    """

    def output_specs(self) -> dict[str, ArraySpec]:
        """Every array ``simulate`` returns (only those the scene asked for)."""
        ...

    def simulate(self, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """``n`` samples as ``{name: array of shape (n, *spec.shape)}``."""
        ...
