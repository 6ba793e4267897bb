"""Arrangements of repeated parts for the strip array: a training set of pressure fields made of many
small parts placed as everyday objects place them, drawn from no named object.

Rounds 2-7 of unseen objects (docs/strips.md) keep finding the same losing kind of family: many parts
of one kind in a regular arrangement - a hairbrush's pins, a keypad, LEGO studs, a notebook's coil,
bubble wrap, braille, a shower head's nozzles, a grater's lips, a keyboard, a chain, a bird's toes. The
shape library draws 0-4 contacts (up to 6 in the wide scene, five-part objects), and random shapes
(``strips_random_shapes.py``) draw islands with no order among them. This script draws the generic
class those objects belong to: **K parts of one primitive on a random lattice**.

A frame: one arrangement (15 %: two, as a safety pin's coil and wires) of 2-30 parts:

- parts: domes (0.3-4 mm radius), flat or domed pads (0.8-15 mm, aspect 1-3), line segments (1.5-25 mm
  long, 0.3-2.5 mm wide) or rings (1-8 mm radius, 0.3-2 mm wide); one kind and size a frame (20 %:
  each part its own kind), sizes jittered 10 % a part;
- arrangements: a grid (1-6 x 2-8, pitches 1.5-20 mm, rows staggered in 40 % of grids, half the grids
  with 0-50 % of the sites left out: dice, braille, key rows), a row along a line or an arc, one or two
  circles (2-18 mm radius), lines radiating from one point, or a cluster scattered in a disc; at any
  angle, centred anywhere within 15 mm of the array's centre (so running off it too);
- parts oriented with the arrangement (half the frames), all at one random angle, or each at its own;
- each part's load jittered (0.6-1), the frame tilted by a linear ramp in 30 % of frames; 0.3-12 N
  in all (log-uniform).

Pushed through the strips16 sensor model with per-frame gains, noise and ADC
(``strips_product_fields.push``); the truth is the sensor model's intersection map; an ordinary
dataset of ``strips16``'s sensor named ``strips16_arrangements``::

    python scripts/strips_arrangements.py --n 30000 --seed 9801 --out data/arrangements-train

Designed after rounds 2-7 were seen (none of them is blind for a model trained on it); the test of such
a model is round 8, written after its declaration (docs/strips.md, "Round 8").
"""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np

from synth.scene import Scene, load_scene

sys.path.insert(0, str(Path(__file__).resolve().parent))
import strips_product_fields as products  # a sibling script: its sensor push and dataset writer

FORCE_N = (0.3, 12.0)  # the frame's total load (log-uniform)
KINDS = ("dome", "pad", "line", "ring")
MIXED_KINDS_SHARE = 0.2  # frames whose parts each take their own kind
SECOND_SHARE = 0.15  # frames with a second arrangement
RAMP_SHARE = 0.3
LAYOUTS = ("grid", "row", "circles", "radial", "cluster")
MAX_PARTS = 30


def arrangements_scene() -> Scene:
    base = load_scene("strips16")
    return dataclasses.replace(
        base,
        name="strips16_arrangements",
        description="the strips16 sensor under arrangements of repeated parts (scripts/strips_arrangements.py)",
    )


def _log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return math.exp(rng.uniform(math.log(low), math.log(high)))


def part_size(kind: str, rng: np.random.Generator) -> tuple[float, float]:
    """A part's two sizes (mm): dome radius (and 0), pad width and length, line length and width,
    ring radius and width."""
    if kind == "dome":
        return _log_uniform(rng, 0.3, 4.0), 0.0
    if kind == "pad":
        width = _log_uniform(rng, 0.8, 15.0)
        return width, width * rng.uniform(1.0, 3.0)
    if kind == "line":
        return _log_uniform(rng, 1.5, 25.0), _log_uniform(rng, 0.3, 2.5)
    return _log_uniform(rng, 1.0, 8.0), _log_uniform(rng, 0.3, 2.0)


def sites(layout: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Part centres (K, 2) in mm about the arrangement's origin, unrotated, and each part's angle
    along the arrangement (rad)."""
    if layout == "grid":
        rows, cols = int(rng.integers(1, 7)), int(rng.integers(2, 9))
        px = _log_uniform(rng, 1.5, 20.0)
        py = px * rng.uniform(0.7, 1.5)
        stagger = rng.uniform(0.25, 0.5) * px if rng.uniform() < 0.4 else 0.0
        r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
        x = (c - (cols - 1) / 2) * px + (r % 2) * stagger
        y = (r - (rows - 1) / 2) * py
        xy = np.stack([x.ravel(), y.ravel()], axis=1)
        if rng.uniform() < 0.5:  # sites left out (a die's face, braille, a row of keys)
            keep = rng.uniform(size=len(xy)) >= rng.uniform(0.0, 0.5)
            xy = xy[keep] if keep.sum() >= 2 else xy[:2]
        return xy, np.zeros(len(xy))
    if layout == "row":
        k = int(rng.integers(2, 15))
        pitch = _log_uniform(rng, 1.5, 15.0)
        s = (np.arange(k) - (k - 1) / 2) * pitch
        if rng.uniform() < 0.4:  # along an arc
            radius = _log_uniform(rng, 8.0, 40.0) * rng.choice([-1.0, 1.0])
            phi = s / radius
            return np.stack([radius * np.sin(phi), radius * (1 - np.cos(phi))], axis=1), phi
        return np.stack([s, np.zeros(k)], axis=1), np.zeros(k)
    if layout == "circles":
        xy, along = [], []
        for _ in range(int(rng.integers(1, 3))):
            k, radius = int(rng.integers(3, 17)), _log_uniform(rng, 2.0, 18.0)
            phi = rng.uniform(0, 2 * math.pi) + np.arange(k) * 2 * math.pi / k
            xy.append(np.stack([radius * np.cos(phi), radius * np.sin(phi)], axis=1))
            along.append(phi + math.pi / 2)
        return np.concatenate(xy), np.concatenate(along)
    if layout == "radial":  # lines from one point: the parts are placed at half their length out
        k = int(rng.integers(3, 9))
        phi = rng.uniform(0, 2 * math.pi) + (
            np.arange(k) * 2 * math.pi / k if rng.uniform() < 0.5 else np.sort(rng.uniform(0, 2 * math.pi, k))
        )
        return np.stack([np.cos(phi), np.sin(phi)], axis=1), phi
    k, radius = int(rng.integers(2, 21)), _log_uniform(rng, 3.0, 20.0)
    rho, phi = radius * np.sqrt(rng.uniform(size=k)), rng.uniform(0, 2 * math.pi, k)
    return np.stack([rho * np.cos(phi), rho * np.sin(phi)], axis=1), rng.uniform(0, math.pi, k)


def raster_part(
    kind: str, size: tuple[float, float], cx: float, cy: float, angle: float, xx: np.ndarray, yy: np.ndarray, h: float
) -> np.ndarray:
    """One part's pressure shape (unit-free, peak 1) on the lattice ``xx, yy`` (mm, pitch ``h``);
    features thinner than the lattice are widened to it (their place kept)."""
    dx, dy = xx - cx, yy - cy
    u = dx * math.cos(angle) + dy * math.sin(angle)
    v = -dx * math.sin(angle) + dy * math.cos(angle)
    a, b = size
    if kind == "dome":
        rr = max(a, 0.6 * h)
        return np.sqrt(np.clip(1.0 - (u * u + v * v) / (rr * rr), 0.0, None))
    if kind == "pad":
        hu, hv = max(a / 2, 0.6 * h), max(b / 2, 0.6 * h)
        inside = (np.abs(u) <= hu) & (np.abs(v) <= hv)
        return inside.astype(np.float64) if a > 4.0 else np.sqrt(np.clip(1 - (u / hu) ** 2 - (v / hv) ** 2, 0, None))
    if kind == "line":  # distance to the segment along u, a rounded section across it
        half = max(b / 2, 0.6 * h)
        d2 = (np.clip(np.abs(u) - a / 2, 0.0, None)) ** 2 + v * v
        return np.sqrt(np.clip(1.0 - d2 / (half * half), 0.0, None))
    half = max(b / 2, 0.6 * h)
    d = np.sqrt(u * u + v * v) - a
    return np.sqrt(np.clip(1.0 - (d * d) / (half * half), 0.0, None))


def arrangement(xx: np.ndarray, yy: np.ndarray, h: float, rng: np.random.Generator) -> np.ndarray:
    """One arrangement's pressure shape (unit-free) on the lattice."""
    layout = LAYOUTS[int(rng.integers(len(LAYOUTS)))]
    xy, along = sites(layout, rng)
    xy, along = xy[:MAX_PARTS], along[:MAX_PARTS]
    kind = "line" if layout == "radial" else KINDS[int(rng.integers(len(KINDS)))]
    size = part_size(kind, rng)
    if layout == "radial":  # each line starts at the centre: its centre half its length out
        xy = xy * (size[0] / 2)
    theta, (ox, oy) = rng.uniform(0, 2 * math.pi), rng.uniform(-15.0, 15.0, 2)
    c, s = math.cos(theta), math.sin(theta)
    centres = np.stack([ox + c * xy[:, 0] - s * xy[:, 1], oy + s * xy[:, 0] + c * xy[:, 1]], axis=1)
    orient = rng.uniform()
    common = rng.uniform(0, math.pi)
    mixed = layout != "radial" and rng.uniform() < MIXED_KINDS_SHARE
    field = np.zeros_like(xx)
    for (cx, cy), a in zip(centres, along, strict=True):
        part_kind = KINDS[int(rng.integers(len(KINDS)))] if mixed else kind
        base = part_size(part_kind, rng) if mixed else size
        jittered = (base[0] * rng.uniform(0.9, 1.1), base[1] * rng.uniform(0.9, 1.1))
        angle = (
            theta + a if orient < 0.5 or layout == "radial" else common if orient < 0.75 else rng.uniform(0, math.pi)
        )
        field += rng.uniform(0.6, 1.0) * raster_part(part_kind, jittered, cx, cy, angle, xx, yy, h)
    return field


def shape(size: int, h_mm: float, rng: np.random.Generator) -> np.ndarray:
    """One non-negative (size, size) pressure shape (unit-free) with a positive sum on the array."""
    x = (np.arange(size) + 0.5) * h_mm - size * h_mm / 2
    xx, yy = np.meshgrid(x, x, indexing="ij")
    p = arrangement(xx, yy, h_mm, rng)
    if rng.uniform() < SECOND_SHARE:
        p += rng.uniform(0.3, 1.0) * arrangement(xx, yy, h_mm, rng)
    if rng.uniform() < RAMP_SHARE:
        angle = rng.uniform(0.0, 2.0 * math.pi)
        ramp = 1.0 + rng.uniform(0.5, 2.0) * (xx * math.cos(angle) + yy * math.sin(angle)) / (size * h_mm)
        p = p * np.clip(ramp, 0.0, None)
    if p.sum() <= 0.0:  # every part off the array: one cell
        p = np.zeros((size, size))
        p[rng.integers(size), rng.integers(size)] = 1.0
    return p


def draw(scene: Scene, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """``n`` frames: readings (B, 32) V and the intersection map (B, 16, 16) kPa."""
    return products.draw_shapes(scene, n, rng, shape, FORCE_N)


def write(n: int, seed: int, out: Path) -> Path:
    """The dataset folder (shards seeded per index, manifest last)."""
    return products.write(n, seed, out, arrangements_scene(), draw)


def main(argv: list[str] | None = None) -> int:
    return products.run_cli(argv, __doc__, write)


if __name__ == "__main__":
    sys.exit(main())
