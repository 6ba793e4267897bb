"""tactile-learn train: train a task's network on CPU."""

from __future__ import annotations

import argparse

from synth.io import json_dumps
from tactile_learn.cli.common import non_negative_int, positive_int
from tactile_learn.tasks import TASK_NAMES

HELP = (
    "train a task's network on a generated dataset or on touches simulated as needed"
    " (CPU or a CUDA GPU, reproducible, resumable)"
)
EXAMPLES = """\
  tactile-learn generate --scene strips16 --n 200000 --seed 1 --out data/s16-train --workers 2
  tactile-learn generate --scene strips16 --n 4000 --seed 2 --out data/s16-val
  tactile-learn train --task strips --data data/s16-train --val data/s16-val --out runs/s16-small
  tactile-learn train --task strips --data data/s16-train --val data/s16-val --out runs/s16-small --resume
  tactile-learn train --task thermal --data data/th-train --val data/th-val --out runs/th --size small
  tactile-learn train --task thermal --scene thermal --stream 160000 --val data/th-val --out runs/th-stream
  tactile-learn train --task thermal --scene thermal --stream 160000 --stream-pixels 4 --val data/th-val --out runs/th4
  tactile-learn train --task strips --data data/mine --val data/mine-val --out runs/tuned --init models/strips16.pt
  tactile-learn train --task strips --data data/mixed-train data/s16-train --val data/mixed-val --out runs/mix
  # the same recipe on a CUDA GPU (batches and validation stay on the CPU; weights saved for the CPU)
  tactile-learn train --task strips --data data/s16-train --val data/s16-val --out runs/s16-gpu --device cuda
  # data-parallel on N processes (DDP, gloo, CPU): each rank trains on its share of every batch, rank 0 writes the run
  torchrun --nproc-per-node 2 -m tactile_learn.cli train --task strips --data data/s16-train --val data/s16-val \
      --out runs/s16-ddp --threads 1
--scene/--stream: every epoch simulates --stream fresh samples (seed --stream-seed; epoch e takes the shards
after epoch e-1's), shuffled like a dataset; --repeat reuses the first epoch's (then training equals training on
`generate --n N --seed S --shard-size B`, same weights). --stream-pixels K (thermal) simulates only K random
pixels of every touch: training reads 4 per touch, so 4 of a 4 x 4 array is the same training at a quarter of the
simulation.
Writes RUN/checkpoint.pt every epoch, then RUN/model.pt (best epoch), RUN/metrics.json and RUN/loss.png."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", required=True, choices=TASK_NAMES)
    parser.add_argument(
        "--data",
        default=None,
        nargs="+",
        help="training dataset folder; several folders of one sensor are read as one training set (a mixture);"
        " or --scene with --stream",
    )
    parser.add_argument("--scene", default=None, help="instead of --data: simulate this scene (name or .toml)")
    parser.add_argument(
        "--stream", type=non_negative_int, default=0, help="with --scene: samples simulated per epoch (nothing written)"
    )
    parser.add_argument(
        "--stream-seed", type=non_negative_int, default=1, help="seed of the simulated samples (as generate --seed)"
    )
    parser.add_argument(
        "--shard-size", type=positive_int, default=8192, help="samples simulated at a time (as generate --shard-size)"
    )
    parser.add_argument(
        "--repeat", action="store_true", help="every epoch the same --stream samples (a dataset) instead of fresh ones"
    )
    parser.add_argument(
        "--stream-pixels",
        type=non_negative_int,
        default=0,
        help="thermal --stream: simulate only K random pixels of every touch (training reads 4; 0: all)",
    )
    parser.add_argument("--val", required=True, help="validation dataset folder (another seed)")
    parser.add_argument("--out", required=True, help="run folder")
    parser.add_argument(
        "--size",
        default="",
        help="network size (task-specific; default: the smallest, or with --init the size of those weights)",
    )
    parser.add_argument("--epochs", type=positive_int, default=0, help="maximum epochs, >= 1 (default: the task's)")
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
    parser.add_argument(
        "--teacher",
        default=None,
        help="distillation: a finished run (RUN) or a model's NAME.pt whose maps are the targets of --teacher-data",
    )
    parser.add_argument(
        "--teacher-data", nargs="+", default=[], help="the --data folders the teacher teaches (the others: the truth)"
    )
    parser.add_argument(
        "--teacher-weight", type=float, default=1.0, help="target = w * teacher + (1 - w) * truth (default 1)"
    )
    parser.add_argument(
        "--r-weight",
        type=float,
        default=1.0,
        help="strips: weight of the loss's per-frame (1 - Pearson r) term beside the MSE (default 1)",
    )
    parser.add_argument(
        "--device",
        default="cpu",
        help="where the network trains: cpu (default, bit-reproducible) or cuda[:N] (a GPU: the same recipe, faster;"
        " weights equal up to the GPU's arithmetic)",
    )
    parser.add_argument(
        "--keep-epochs",
        action="store_true",
        help="also write every epoch's weights as RUN/epoch-NNN.pt (for an average of the last epochs)",
    )
    parser.add_argument("--quiet", action="store_true")


def run(args: argparse.Namespace) -> int:
    from tactile_learn.train import TrainConfig, train

    config = TrainConfig(
        task=args.task,
        data=("" if not args.data else args.data[0] if len(args.data) == 1 else tuple(args.data)),
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
        scene=args.scene or "",
        stream=args.stream,
        stream_seed=args.stream_seed,
        shard_size=args.shard_size,
        fresh=not args.repeat,
        stream_pixels=args.stream_pixels,
        teacher=args.teacher,
        teacher_data=tuple(args.teacher_data),
        teacher_weight=args.teacher_weight,
        r_weight=args.r_weight,
        device=args.device,
        keep_epochs=args.keep_epochs,
    )
    result = train(config, resume=args.resume, progress=False if args.quiet else None)
    if not args.quiet and "val_metrics" in result:  # under torchrun: rank 0 reports
        summary = {k: result[k] for k in ("task", "size", "epochs_run", "best_epoch", "train_seconds", "val_metrics")}
        print(json_dumps(summary))
    return 0
