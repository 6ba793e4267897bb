"""Average the weights of two fine-tuned runs of one network (a "model soup"): both must share the
architecture, size and normalisation (a run fine-tuned with ``train --init`` from the other does).
The result is a run folder that ``tactile-learn export`` reads like any other.

    python scripts/average_weights.py runs/strips16_single runs/strips16_mix --last-epoch --out runs/strips16_soup

``--last-epoch`` takes the second run's weights at its last epoch (``RUN/checkpoint.pt``) instead of
its best validation epoch (``RUN/model.pt``): a run validated on one distribution may have kept an
early epoch that the average does not want.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from synth.errors import ConfigError, ModelError
from tactile_learn.checkpoints import MODEL, load_torch, load_weights, save_torch
from tactile_learn.train import CHECKPOINT


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("first", help="a run folder or a model's NAME.pt")
    parser.add_argument("second", help="a run folder (its card and scene are kept)")
    parser.add_argument("--weight", type=float, default=0.5, help="share of the second run's weights")
    parser.add_argument("--last-epoch", action="store_true", help="the second run's last epoch, not its best")
    parser.add_argument("--out", required=True, help="run folder to write")
    args = parser.parse_args(argv)
    if not 0.0 <= args.weight <= 1.0:
        raise ConfigError(f"--weight: {args.weight} is out of range [0, 1]")
    a, b = load_weights(args.first), load_weights(args.second)
    if (a["task"], a["size"], a["stats"]) != (b["task"], b["size"], b["stats"]):
        raise ModelError(f"{args.first} and {args.second} differ in task, size or normalisation: nothing to average")
    sa, sb = a["state_dict"], b["state_dict"]
    if args.last_epoch:
        checkpoint = Path(args.second) / CHECKPOINT
        if not checkpoint.is_file():
            raise ModelError(f"{checkpoint}: no checkpoint (--last-epoch needs a run folder)")
        sb = load_torch(checkpoint)["net"]
    if sa.keys() != sb.keys() or any(sa[k].shape != sb[k].shape for k in sa):
        raise ModelError(f"{args.first} and {args.second} hold different networks")
    w = args.weight
    soup = {k: (1 - w) * sa[k] + w * sb[k] if sb[k].is_floating_point() else sb[k] for k in sb}
    averaged = {"first": str(args.first), "second": str(args.second), "weight": w, "last_epoch": args.last_epoch}
    result = {**b["result"], "averaged": averaged}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    save_torch(out / MODEL, {**b, "state_dict": soup, "result": result})
    print(f"{out / MODEL}: {1 - w:g} x {args.first} + {w:g} x {args.second}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
