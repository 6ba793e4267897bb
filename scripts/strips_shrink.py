"""Start a smaller general strip network (architecture 2) from a trained larger one, for fine-tuning
(``tactile-learn train --init``): the channels, context units and mixing blocks the smaller size
keeps are the larger network's most used ones, so training starts from a working inverse instead of
from scratch (measured: docs/strips.md, strips Pareto section).

Which ones are kept: per layer, the units whose outgoing weights have the largest norm (a unit the
next layer barely reads matters least); the first mixing blocks; the head reads the kept channels.
Both sizes must share the base (``small`` -> ``tiny``, ``small_law`` -> ``tiny_law``).

    python scripts/strips_shrink.py models/strips16.pt --size tiny --out runs/tiny_init.pt
    tactile-learn train --task strips --size tiny --init runs/tiny_init.pt ...
"""

from __future__ import annotations

import argparse
import sys

import torch

from synth.errors import ConfigError
from tactile_learn.nets.strips_general import SIZES
from tactile_learn.train_resize import load_general_source, write_resized


def _keep(outgoing: torch.Tensor, k: int) -> torch.Tensor:
    """Indices (sorted) of the ``k`` input units of ``outgoing`` (out, in, ...) with the largest norm."""
    norms = outgoing.transpose(0, 1).reshape(outgoing.shape[1], -1).norm(dim=1)
    return norms.topk(k).indices.sort().values


def shrink(state: dict[str, torch.Tensor], size: str, blocks_from: int) -> dict[str, torch.Tensor]:
    """The state dict of a ``size`` network holding the kept part of ``state`` (``blocks_from`` blocks)."""
    enc, hidden, context, blocks, correct = SIZES[size]
    if correct:
        raise ConfigError(f"--size {size}: the correction step's layers have no counterpart to shrink from")
    if blocks > blocks_from:
        raise ConfigError(f"--size {size} has {blocks} mixing blocks, the source only {blocks_from}")
    s = {k: v.clone() for k, v in state.items()}
    out: dict[str, torch.Tensor] = {"loads.segments": s["loads.segments"]}
    big_enc = s["crossings.row_proj.weight"].shape[1] - 1
    big_hidden = s["crossings.row_proj.weight"].shape[0]
    # hidden channels: read by the first block (own and pooled weights) and, after it, the head
    first = [s["blocks.0.own.weight"], s["blocks.0.along_rows.weight"], s["blocks.0.along_cols.weight"]]
    usage = first[0][:, :, 0, 0].norm(dim=0) + sum(
        w[:, :big_hidden, 0, 0].norm(dim=0) + w[:, big_hidden:, 0, 0].norm(dim=0) for w in first[1:]
    )
    h = usage.topk(hidden).indices.sort().values
    pooled = torch.cat([h, h + big_hidden])  # max and mean halves of the pooled features
    for side in ("row", "col"):
        proj = s[f"crossings.{side}_proj.weight"]
        e = _keep(proj[:, :big_enc], enc)
        prefix = f"crossings.{side}_encoder"
        layers = (0, 2, 4)
        keep_in = torch.arange(1)
        for i, layer in enumerate(layers):
            keep_out = e if i == len(layers) - 1 else _keep(s[f"{prefix}.{layers[i + 1]}.weight"], enc)
            out[f"{prefix}.{layer}.weight"] = s[f"{prefix}.{layer}.weight"][keep_out][:, keep_in]
            out[f"{prefix}.{layer}.bias"] = s[f"{prefix}.{layer}.bias"][keep_out]
            keep_in = keep_out
        cols = torch.cat([e, torch.tensor([big_enc])])  # the encoded channels and the raw profile
        out[f"crossings.{side}_proj.weight"] = proj[h][:, cols]
    out["crossings.row_proj.bias"] = s["crossings.row_proj.bias"][h]
    out["crossings.physics_proj.weight"] = s["crossings.physics_proj.weight"][h]
    c2 = _keep(s["context.4.weight"], context)
    c1 = _keep(s["context.2.weight"][c2], context)
    out["context.0.weight"], out["context.0.bias"] = s["context.0.weight"][c1], s["context.0.bias"][c1]
    out["context.2.weight"], out["context.2.bias"] = s["context.2.weight"][c2][:, c1], s["context.2.bias"][c2]
    out["context.4.weight"], out["context.4.bias"] = s["context.4.weight"][h][:, c2], s["context.4.bias"][h]
    for b in range(blocks):
        out[f"blocks.{b}.own.weight"] = s[f"blocks.{b}.own.weight"][h][:, h]
        out[f"blocks.{b}.own.bias"] = s[f"blocks.{b}.own.bias"][h]
        for pool in ("along_rows", "along_cols"):
            out[f"blocks.{b}.{pool}.weight"] = s[f"blocks.{b}.{pool}.weight"][h][:, pooled]
    out["head.weight"], out["head.bias"] = s["head.weight"][:, h], s["head.bias"]
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("source", help="a trained general network: run folder or a model's NAME.pt")
    parser.add_argument("--size", required=True, help="the smaller size (strips_general.SIZES)")
    parser.add_argument("--out", required=True, help="weights file to write (for train --init)")
    args = parser.parse_args(argv)
    saved = load_general_source(args.source, args.size)
    if args.size.endswith("_law") != str(saved["size"]).endswith("_law"):
        raise ConfigError(f"--size {args.size}: the source ({saved['size']}) has the other base map")
    blocks_from = SIZES[str(saved["size"])][3]
    state = shrink(saved["state_dict"], args.size, blocks_from)
    write_resized(saved, args.size, state, args.out, "shrunk_from", args.source)
    return 0


if __name__ == "__main__":
    sys.exit(main())
