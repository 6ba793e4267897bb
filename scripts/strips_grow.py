"""Start a deeper or wider general strip network (architecture 2) from a trained one, for
fine-tuning (``tactile-learn train --init``). The grown network computes exactly what the trained
one does, so training only adds:

- an added mixing block starts at the identity (its weights and biases zero: ``relu(x + 0) = x``
  on the non-negative features it reads);
- added crossing channels (a wider size) start with fresh random weights *into* them and zero
  weights *out of* them (no trained channel, and not the head, reads them yet): their features are
  alive, so the loss has a gradient on the weights that will read them;
- a wider global context (more hidden units in its MLP) the same way: fresh weights into the added
  units, zero weights out of them.

    python scripts/strips_grow.py models/strips16.pt --size deep --out runs/deep_init.pt
    python scripts/strips_grow.py models/strips16.pt --size wide --out runs/wide_init.pt
    python scripts/strips_grow.py models/strips16.pt --size context384_consistent --out runs/context_init.pt
    tactile-learn train --task strips --size wide --init runs/wide_init.pt ...

A size that only adds the consistency step (``wide`` -> ``wide_consistent``) takes the weights as
they are (the step has none); its map is then the source's after one step through the forward model.
"""

from __future__ import annotations

import argparse
import sys

import torch

from synth.errors import ConfigError
from tactile_learn.checkpoints import weights_scene
from tactile_learn.nets.strips_general import SIZES, GeneralStripNet
from tactile_learn.train_resize import load_general_source, write_resized

__all__ = ["grow", "main", "widen", "widen_context"]

#: the layers writing crossing channels (output rows) and reading them (input columns)
_WRITERS = ("crossings.row_proj.weight", "crossings.row_proj.bias", "crossings.col_proj.weight")
_WRITERS += ("crossings.physics_proj.weight", "context.4.weight", "context.4.bias")


def widen(state: dict[str, torch.Tensor], fresh: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """``state`` (a trained network) inside ``fresh`` (a freshly initialised wider one, same number
    of blocks): trained weights in the first channels, fresh weights into the added channels, zero
    weights from them into the trained channels and the head."""
    out = {k: v.clone() for k, v in fresh.items()}
    old, new = int(state["head.weight"].shape[1]), int(fresh["head.weight"].shape[1])
    if new < old:
        raise ConfigError(f"the target has {new} crossing channels, fewer than the source's {old}")
    for name, value in state.items():
        if name.startswith("blocks."):
            continue
        if name in _WRITERS:
            out[name][:old] = value
        elif name == "head.weight":
            out[name].zero_()
            out[name][:, :old] = value
        else:
            out[name] = value.clone()
    blocks = {name.split(".")[1] for name in state if name.startswith("blocks.")}
    for b in sorted(blocks):
        key = f"blocks.{b}"
        own = out[f"{key}.own.weight"]
        own[:old, old:] = 0.0  # trained channels do not read the added ones
        own[:old, :old] = state[f"{key}.own.weight"]
        out[f"{key}.own.bias"][:old] = state[f"{key}.own.bias"]
        for axis in ("along_rows", "along_cols"):
            # inputs: [max over the axis (channels), mean over the axis (channels)]
            weight, trained = out[f"{key}.{axis}.weight"], state[f"{key}.{axis}.weight"]
            weight[:old] = 0.0
            weight[:old, :old] = trained[:, :old]
            weight[:old, new : new + old] = trained[:, old:]
    return out


def widen_context(state: dict[str, torch.Tensor], fresh: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """``state`` inside ``fresh``, a network whose global context MLP is wider (same crossing
    channels and blocks): the added hidden units take fresh weights from their inputs and zero
    weights into every trained unit and into the context's output, so the map is unchanged."""
    out = {k: v.clone() for k, v in state.items()}
    old, new = int(state["context.2.weight"].shape[0]), int(fresh["context.2.weight"].shape[0])
    if new < old:
        raise ConfigError(f"the target's context has {new} units, fewer than the source's {old}")
    for layer in ("context.0", "context.2"):  # rows: units; the added ones read their inputs fresh
        weight, bias = fresh[f"{layer}.weight"].clone(), fresh[f"{layer}.bias"].clone()
        columns = state[f"{layer}.weight"].shape[1]
        if layer == "context.2":
            weight[:old, old:] = 0.0  # trained units do not read the added ones
        weight[:old, :columns] = state[f"{layer}.weight"]
        bias[:old] = state[f"{layer}.bias"]
        out[f"{layer}.weight"], out[f"{layer}.bias"] = weight, bias
    head = torch.zeros_like(fresh["context.4.weight"])
    head[:, :old] = state["context.4.weight"]  # the context's output does not read the added units yet
    out["context.4.weight"] = head
    return out


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
    parser.add_argument("--size", required=True, help="the deeper or wider size (strips_general.SIZES)")
    parser.add_argument("--out", required=True, help="weights file to write (for train --init)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the added channels' fresh weights")
    args = parser.parse_args(argv)
    saved = load_general_source(args.source, args.size)
    spec, source = SIZES[args.size], SIZES[str(saved["size"])]
    if spec[1:3] == source[1:3]:
        state = grow(saved["state_dict"], args.size, str(saved["size"]))
    else:
        # one dimension at a time: crossing channels or the context's width, nothing else
        widened = [i for i in range(5) if spec[i] != source[i]]
        if widened not in ([1], [2]):
            raise ConfigError(
                f"--size {args.size}: only the number of mixing blocks, or (alone) of crossing channels or of "
                f"the context's units may differ from {saved['size']}"
            )
        torch.manual_seed(args.seed)
        fresh = GeneralStripNet(weights_scene(saved), saved["stats"], args.size).state_dict()
        state = (widen if widened == [1] else widen_context)(saved["state_dict"], fresh)
    if "scene" not in saved:  # a shipped NAME.pt keeps its scene in the card: train --init needs it in the file
        saved = {**saved, "scene": weights_scene(saved).to_dict()}
    write_resized(saved, args.size, state, args.out, "grown_from", args.source)
    return 0


if __name__ == "__main__":
    sys.exit(main())
