"""Frames of one family of an evaluation suite, written as an ordinary dataset (a specialist's training data).

A suite's family is a whole scene (``synth.suite.Family.scene``); this writes ``n`` of its frames with the
dataset writer (``synth.dataset.generate``), so ``tactile-learn train --data`` reads them like any other
dataset. Used to fine-tune a diagnostic specialist on one family that the default strip model loses
(docs/strips.md, "What a specialist reaches on the losing families")::

    python scripts/strips_family_data.py --suite strips16_unseen4 --family hairbrush_pins \\
        --n 30000 --seed 9101 --out data/fam-hairbrush_pins-train

Evaluate such a specialist at seeds other than ``--seed``: ``synth.suite.suite_frames`` draws family ``i``
from ``SeedSequence(seed, spawn_key=(i,))`` and this dataset's shard ``i`` from the same expression, so the
same seed would share frames with the training data.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from synth.dataset import generate
from synth.suite import load_suite


def write_family(suite: str, family: str, n: int, seed: int, out: str | Path, workers: int = 1) -> Path:
    """Write ``n`` frames of ``family`` of ``suite`` (a shipped name or a TOML path) to ``out``; returns the
    manifest's path. An unknown family raises ``ConfigError`` listing the suite's families."""
    scene = load_suite(suite).family(family).scene
    return generate(scene, n, seed, out, workers=workers)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--suite", required=True, help="a shipped suite's name or a suite TOML file")
    parser.add_argument("--family", required=True, help="the family's name in that suite")
    parser.add_argument("--n", type=int, required=True, help="frames to write")
    parser.add_argument("--seed", type=int, required=True)
    parser.add_argument("--out", required=True, help="dataset folder")
    parser.add_argument("--workers", type=int, default=1, help="processes simulating shards (default 1)")
    args = parser.parse_args(argv)
    manifest = write_family(args.suite, args.family, args.n, args.seed, args.out, args.workers)
    print(f"{args.suite}/{args.family}: {args.n} frames, seed {args.seed} -> {manifest}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
