"""Can the strip readings tell two kinds of frame apart? A held-out classifier on the 32 readings.

Random-shape training (``strips_random_shapes.py``) lifts the unseen rounds and costs the ood suite's
diagonal edge (docs/strips.md, "Random shapes"). Is that an information limit - a diagonal line and the
random shapes that load as many strips give readings no function can tell apart, so one network must
answer both with one hedge - or a learning one? This trains a small classifier (two hidden layers of 256,
Adam, 60 epochs) on three quarters of the two sets' frames and reports its accuracy on the last quarter:
near 0.5, no network can serve both priors from these readings; near 1, one could.

Features: each frame's readings above the unloaded level, as shares of their total (the map's shape),
and the log of the total. The random shapes are kept only where they load at least as many strips as
the 10th percentile of the other set (frames that cover a few strips are told apart trivially)::

    python scripts/strips_separability.py --family strips16_ood:diagonal_edge --n 4000 --seed 77
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

from synth.suite import load_suite
from tactile_learn.suites import suite_frames

sys.path.insert(0, str(Path(__file__).resolve().parent))
import strips_random_shapes as shapes  # a sibling script: the random shapes

HIDDEN = 256
EPOCHS = 60
ACTIVE_V = 0.01  # a strip reading this far above the unloaded level carries load (5 noise levels)


def features(readings: np.ndarray, offset_v: float) -> np.ndarray:
    """(B, 33): the loads as shares of their total (times the strip count), and the log of the total."""
    loads = np.clip(readings - offset_v, 0.0, None)
    total = loads.sum(axis=1, keepdims=True) + 1e-9
    return np.hstack([loads / total * loads.shape[1], np.log(total)]).astype(np.float32)


def held_out_accuracy(a: np.ndarray, b: np.ndarray, seed: int, epochs: int = EPOCHS) -> float:
    """Accuracy on a held-out quarter of a classifier telling feature rows ``a`` from ``b``."""
    import torch  # training happens here only

    x = np.vstack([a, b])
    y = np.r_[np.ones(len(a)), np.zeros(len(b))].astype(np.float32)
    order = np.random.default_rng(seed).permutation(len(x))
    x, y = x[order], y[order]
    split = len(x) * 3 // 4
    mean, std = x[:split].mean(axis=0), x[:split].std(axis=0) + 1e-6
    x = (x - mean) / std
    torch.manual_seed(seed)
    net = torch.nn.Sequential(
        torch.nn.Linear(x.shape[1], HIDDEN),
        torch.nn.ReLU(),
        torch.nn.Linear(HIDDEN, HIDDEN),
        torch.nn.ReLU(),
        torch.nn.Linear(HIDDEN, 1),
    )
    optimiser = torch.optim.Adam(net.parameters(), 1e-3)
    xt, yt = torch.from_numpy(x[:split]), torch.from_numpy(y[:split])
    generator = torch.Generator().manual_seed(seed)
    for _ in range(epochs):
        for batch in torch.randperm(split, generator=generator).split(256):
            optimiser.zero_grad()
            loss = torch.nn.functional.binary_cross_entropy_with_logits(net(xt[batch]).squeeze(1), yt[batch])
            loss.backward()
            optimiser.step()
    with torch.no_grad():
        guess = (net(torch.from_numpy(x[split:])).squeeze(1) > 0).numpy()
    return float((guess == (y[split:] > 0.5)).mean())


def family_against_shapes(suite_name: str, family: str, n: int, seed: int) -> dict[str, float]:
    """``n`` frames of the family against ``n`` random shapes loading as many strips; the accuracy."""
    suite = load_suite(suite_name)
    one = dataclasses.replace(suite, families=(suite.family(family),))
    frames = suite_frames(one, n, seed)[family]
    scene = shapes.shapes_scene()
    offset = scene.sensor.readout.offset_v
    drawn = shapes.draw(scene, 4 * n, np.random.default_rng(seed + 1))
    active = ((frames["readings"] - offset) > ACTIVE_V).mean(axis=1)
    shape_active = ((drawn["readings"] - offset) > ACTIVE_V).mean(axis=1)
    kept = drawn["readings"][shape_active >= np.quantile(active, 0.1)][:n]
    if len(kept) < n // 2:
        raise ValueError(f"only {len(kept)} random shapes load as many strips as {family}: draw more")
    accuracy = held_out_accuracy(features(frames["readings"], offset), features(kept, offset), seed)
    return {"family_frames": float(n), "shape_frames": float(len(kept)), "held_out_accuracy": accuracy}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--family", required=True, help="SUITE:FAMILY, e.g. strips16_ood:diagonal_edge")
    parser.add_argument("--n", type=int, default=4000)
    parser.add_argument("--seed", type=int, default=77)
    args = parser.parse_args(argv)
    suite_name, _, family = args.family.partition(":")
    if not family:
        parser.error("--family: expected SUITE:FAMILY")
    print(family_against_shapes(suite_name, family, args.n, args.seed))
    return 0


if __name__ == "__main__":
    sys.exit(main())
