"""Resizing a trained general strip network (architecture 2) for fine-tuning: the shared steps of
``scripts/strips_shrink.py`` and ``scripts/strips_grow.py`` (load and check the source, write the
resized weights for ``tactile-learn train --init``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch

from synth.errors import ConfigError, ModelError
from tactile_learn.checkpoints import load_weights, save_torch
from tactile_learn.nets.strips_general import SIZES

__all__ = ["load_general_source", "write_resized"]


def load_general_source(source: str, size: str) -> dict[str, Any]:
    """The saved weights at ``source`` (run folder or NAME.pt), refused unless they are a general
    strip network and ``size`` is one of :data:`~tactile_learn.nets.strips_general.SIZES`."""
    saved = load_weights(source)
    if saved["task"] != "strips" or saved["stats"].get("arch") != 2:
        raise ModelError(f"{source}: not a general strip network (architecture 2)")
    if size not in SIZES:
        raise ConfigError(f"--size {size!r} is not one of {', '.join(SIZES)}")
    return saved


def write_resized(
    saved: dict[str, Any], size: str, state: dict[str, torch.Tensor], out: str, origin_key: str, source: str
) -> None:
    """Write ``saved`` with ``size`` and ``state`` to ``out``, noting ``source`` under ``origin_key``."""
    result = {**saved, "size": size, "state_dict": state, origin_key: str(source)}
    result.pop("source", None)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    save_torch(Path(out), result)
    print(f"{out}: {size} network from {source} ({saved['size']})")
