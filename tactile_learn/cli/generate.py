"""tactile-learn generate: simulate a sharded, seeded dataset."""

from __future__ import annotations

import argparse
import time
from contextlib import ExitStack

from synth.dataset import generate
from synth.scene import load_scene
from tactile_learn.cli.common import non_negative_int, on_off, positive_int
from tactile_learn.progress import progress_bar

HELP = "simulate a sharded, seeded, resumable dataset of a scene"
EXAMPLES = """\
  tactile-learn generate --scene strips16 --n 100000 --seed 1 --out data/strips16-train --workers 2
  tactile-learn generate --scene strips16 --n 5000 --seed 2 --out data/strips16-val
  tactile-learn generate --scene my_sensor.toml --n 2000 --seed 7 --out data/mine --noise off
  tactile-learn generate --scene strips16 --n 400000 --seed 1 --out data/big --cluster --workers 2
  tactile-learn generate --scene strips16 --n 400000 --seed 1 --out data/big --scheduler tcp://10.0.0.5:8786
Rerunning the same command after an interruption finishes the missing shards only; the same seed gives
the same bytes for any --workers, locally or on a Dask cluster (--cluster: a local one of --workers
processes; --scheduler: a running one; the shards come back to this process, which writes them).
A folder holding a different dataset is refused without --overwrite."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scene", required=True, help="shipped scene name or path to a scene .toml")
    parser.add_argument("--n", required=True, type=positive_int, help="number of samples")
    parser.add_argument("--seed", required=True, type=non_negative_int, help="dataset seed")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--workers", type=positive_int, default=1, help="worker processes (default 1)")
    parser.add_argument("--shard-size", type=positive_int, default=8192, help="samples per shard (default 8192)")
    parser.add_argument("--noise", type=on_off, default=None, help="on|off: override the scene's noise switch")
    parser.add_argument("--outputs", default=None, help="comma-separated outputs to keep (default: the scene's)")
    parser.add_argument("--overwrite", action="store_true", help="replace a different dataset in --out")
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    parser.add_argument("--cluster", action="store_true", help="simulate the shards on a local Dask cluster")
    parser.add_argument("--scheduler", default=None, help="simulate the shards on a running Dask scheduler (ADDRESS)")
    parser.add_argument("--report", default=None, help="with a cluster: write Dask's HTML performance report here")


def run(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene)
    if args.noise is not None:
        scene = scene.with_noise(args.noise)
    if args.outputs:
        scene = scene.with_outputs(tuple(o.strip() for o in args.outputs.split(",") if o.strip()))
    start = time.perf_counter()
    with ExitStack() as stack:
        executor = None
        if args.cluster or args.scheduler:
            from tactile_learn.cluster import cluster_client, performance_report

            client = stack.enter_context(cluster_client(args.scheduler, workers=args.workers))
            stack.enter_context(performance_report(args.report))
            executor = client.get_executor()
        bar = stack.enter_context(
            progress_bar(args.n, f"generate {scene.name}", "samples", enabled=None if not args.quiet else False)
        )
        manifest = generate(
            scene,
            args.n,
            args.seed,
            args.out,
            shard_size=args.shard_size,
            workers=args.workers,
            overwrite=args.overwrite,
            progress=bar.update,
            executor=executor,
        )
    elapsed = time.perf_counter() - start
    if not args.quiet:
        rate = args.n / elapsed if elapsed > 0 else float("inf")
        print(
            f"wrote {args.n} samples of scene {scene.name} ({scene.digest}) to {manifest.parent} "
            f"in {elapsed:.1f} s ({rate:,.0f} samples/s)"
        )
    return 0
