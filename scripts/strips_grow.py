"""Start a deeper general strip network (architecture 2) from a trained one, for fine-tuning
(``tactile-learn train --init``): the trained layers are copied, and each added mixing block starts
at the identity (its weights and biases zero: ``relu(x + 0) = x`` on the non-negative features it
reads), so the grown network computes exactly what the trained one does and training only adds.

    python scripts/strips_grow.py models/strips16.pt --size deep --out runs/deep_init.pt
    tactile-learn train --task strips --size deep --init runs/deep_init.pt ...
"""

from __future__ import annotations

import argparse
import sys

import torch

from synth.errors import ConfigError
from tactile_learn.nets.strips_general import SIZES
from tactile_learn.train_resize import load_general_source, write_resized

__all__ = ["grow", "main"]


def grow(state: dict[str, torch.Tensor], size: str, source_size: str) -> dict[str, torch.Tensor]:
    """The state dict of a ``size`` network: ``state`` (of a ``source_size`` one) plus identity blocks."""
    spec, source = SIZES[size], SIZES[source_size]
    if spec[:3] != source[:3] or spec[4] != source[4]:
        raise ConfigError(f"--size {size}: only the number of mixing blocks may differ from {source_size}")
    if spec[3] < source[3]:
        raise ConfigError(f"--size {size} has fewer mixing blocks than {source_size} (scripts/strips_shrink.py)")
    out = {k: v.clone() for k, v in state.items()}
    for b in range(source[3], spec[3]):
        template = source[3] - 1  # shapes from the last trained block
        for name in ("own.weight", "own.bias", "along_rows.weight", "along_cols.weight"):
            out[f"blocks.{b}.{name}"] = torch.zeros_like(state[f"blocks.{template}.{name}"])
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("source", help="a trained general network: run folder or a model's NAME.pt")
    parser.add_argument("--size", required=True, help="the deeper size (strips_general.SIZES)")
    parser.add_argument("--out", required=True, help="weights file to write (for train --init)")
    args = parser.parse_args(argv)
    saved = load_general_source(args.source, args.size)
    state = grow(saved["state_dict"], args.size, str(saved["size"]))
    write_resized(saved, args.size, state, args.out, "grown_from", args.source)
    return 0


if __name__ == "__main__":
    sys.exit(main())
