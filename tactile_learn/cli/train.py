"""tactile-learn train: train a task's network on CPU."""

from __future__ import annotations

import argparse

from synth.io import json_dumps
from tactile_learn.cli.common import non_negative_int, positive_int
from tactile_learn.tasks import TASK_NAMES

HELP = "train a task's network on a generated dataset (CPU, reproducible, resumable)"
EXAMPLES = """\
  tactile-learn generate --scene strips16 --n 200000 --seed 1 --out data/s16-train --workers 2
  tactile-learn generate --scene strips16 --n 4000 --seed 2 --out data/s16-val
  tactile-learn train --task strips --data data/s16-train --val data/s16-val --out runs/s16-small
  tactile-learn train --task strips --data data/s16-train --val data/s16-val --out runs/s16-small --resume
  tactile-learn train --task thermal --data data/th-train --val data/th-val --out runs/th --size small
  tactile-learn train --task strips --data data/mine --val data/mine-val --out runs/tuned --init models/strips16.pt
  tactile-learn train --task strips --data data/mixed-train data/s16-train --val data/mixed-val --out runs/mix
Writes RUN/checkpoint.pt every epoch, then RUN/model.pt (best epoch), RUN/metrics.json and RUN/loss.png."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", required=True, choices=TASK_NAMES)
    parser.add_argument(
        "--data",
        required=True,
        nargs="+",
        help="training dataset folder; several folders of one sensor are read as one training set (a mixture)",
    )
    parser.add_argument("--val", required=True, help="validation dataset folder (another seed)")
    parser.add_argument("--out", required=True, help="run folder")
    parser.add_argument("--size", default="", help="network size (task-specific; default: the smallest)")
    parser.add_argument("--epochs", type=non_negative_int, default=0, help="maximum epochs (default: the task's)")
    parser.add_argument("--batch-size", type=positive_int, default=256)
    parser.add_argument("--lr", type=float, default=3e-3, help="peak learning rate (one-cycle)")
    parser.add_argument("--seed", type=non_negative_int, default=0)
    parser.add_argument("--patience", type=positive_int, default=6, help="early stopping patience (epochs)")
    parser.add_argument("--val-limit", type=positive_int, default=4000, help="validation frames per epoch")
    parser.add_argument("--threads", type=non_negative_int, default=0, help="torch threads (default: all cores)")
    parser.add_argument("--max-batches", type=non_negative_int, default=0, help="cap batches per epoch (0: all)")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out from its checkpoint")
    parser.add_argument(
        "--init", default=None, help="start from the weights of a finished run (RUN) or a model's NAME.pt (fine-tuning)"
    )
    parser.add_argument("--quiet", action="store_true")


def run(args: argparse.Namespace) -> int:
    from tactile_learn.train import TrainConfig, train

    config = TrainConfig(
        task=args.task,
        data=args.data[0] if len(args.data) == 1 else tuple(args.data),
        val=args.val,
        out=args.out,
        size=args.size,
        epochs=args.epochs,
        batch_size=args.batch_size,
        lr=args.lr,
        seed=args.seed,
        patience=args.patience,
        val_limit=args.val_limit,
        threads=args.threads,
        max_batches=args.max_batches,
        init=args.init,
    )
    result = train(config, resume=args.resume, progress=False if args.quiet else None)
    if not args.quiet:
        summary = {k: result[k] for k in ("task", "size", "epochs_run", "best_epoch", "train_seconds", "val_metrics")}
        print(json_dumps(summary))
    return 0
