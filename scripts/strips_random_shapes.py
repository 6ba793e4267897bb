"""Random shapes for the strip array: a training set of pressure fields drawn from no named object.

Every learned prior so far was built from named shapes (spheres, punches, blocks, rings, objects made of
them), and every blind round of unseen objects found the families that prior does not cover (docs/strips.md).
Product fields (``strips_product_fields.py``: ``f(x) g(y)``, the intersection rule's own case) were the
first training data drawn from *no* object, and the first to lift every family of a later round; they cost
the lines across the diagonal and a little of the two spheres. This script draws the generic counterpart
that is not a product: the shapes of a thresholded, anisotropically smoothed random field.

A frame: white noise on an 80 x 80 mm lattice centred on the 40 x 40 mm array (the array's own fine
lattice, ``samples_per_pitch`` cells per pitch; the margin keeps the FFT's wrap-around off the array and lets
shapes run off it), smoothed by a Gaussian of correlation lengths ``l`` and ``l * aspect`` at a random
angle (``l`` 0.6-20 mm log-uniform, ``aspect`` 1-25: round specks to long thin streaks at any angle), and
cut at the level that covers a random share of the array (2 % to all of it, log-uniform): many small
islands, a few large patches, lines and strings at any angle, areas larger than the array. In 30 % of
frames only the shape's rim is kept (1-4 cells deep: rings, rims, walls); the pressure on the shape is flat
(a rigid object, half the frames) or rises with the field above the cut (a soft one), in 30 % of frames
tilted by a linear ramp; 0.5-10 N in all. Pushed through the strips16 sensor model with per-frame gains,
noise and ADC (``strips_product_fields.push``); the truth is the sensor model's intersection map. The folder
is an ordinary dataset (manifest, checksummed shards) of ``strips16``'s sensor named
``strips16_random_shapes``::

    python scripts/strips_random_shapes.py --n 30000 --seed 9701 --out data/shapes-train

**The test, declared here before any training or evaluation** (stop 30). Two fine-tunes of the shipped
weights, 8 epochs, lr 3e-4, one thread each, best epoch on ``data/pf-wide-val`` (as the product-field runs):

- ``shapes``: ``products33``'s data (``data/pf-wide-train``, ``data/pf-spheres-train``,
  ``data/products-train``) plus 30,000 random shapes (``data/shapes-train``, seed 9701), the truth the
  target everywhere;
- ``shapesd``: the same frames with ``strips16`` as the teacher of the wide and two-sphere frames
  (``--teacher models/strips16.pt --teacher-data data/pf-wide-train data/pf-spheres-train``), the truth on
  the product fields and the random shapes (``products33d``'s way of keeping the two spheres).

Each is exported (``tactile-learn export runs/RUN --out runs/RUN/model.onnx``; that name replaces the run's
``model.pt`` with the exported weights and needs ``--overwrite``: the later runs were exported to
``runs/RUN/candidate.onnx``, which keeps it) and judged beside
``strips16`` by ``scripts/strips_unseen.py`` (seeds 5151 / 6262, 600 frames a family) on the ood suite,
round 5 (not blind: written before, and product fields were designed after it) and **round 6**, a new
round of unseen objects written after this declaration and after both runs are fixed, and on the
two-sphere test set (``tactile-learn eval --task strips --data data/strips16-test``). A candidate to ship
if two spheres >= 0.96, the ood margin >= +0.05 and both rounds 5 and 6 are at least ``strips16``'s; the
issue's floor is round 6 at +0.05 with no family below the rule.

**Measured** (results/strips_shapes/): two spheres 0.9584 / 0.9602 (``shapes`` / ``shapesd``; ``strips16``
0.9613), ood margin +0.040 / +0.046 (+0.051), round 5 -0.008 / -0.017 (-0.040), round 6 -0.008 / -0.011
(-0.038): neither meets the criteria. **Two more, declared after those figures and before either was made**
(round 6 is not blind for them: it was seen):

- ``soup50``: the mean of ``strips16``'s and ``shapes``' weights (``python scripts/average_weights.py
  models/strips16.pt runs/shapes --weight 0.5 --out runs/soup50``), no training (``shapes``' run file had
  been replaced by its export, above: it was rebuilt as ``runs/shapes/run/model.pt`` from the same weights,
  its card's scene and its ``metrics.json``, and averaged from there);
- ``shapesm``: ``shapesd``'s frames plus 40,000 ``strips16_mixed`` frames (the shape library the ood suite
  holds parameters out of; ``tactile-learn generate --scene strips16_mixed --n 40000 --seed 9702 --out
  data/shapes-mixed-train --workers 2``) taught by ``strips16`` too, 8 epochs, one thread.

The same criteria; one meeting the two-sphere and ood criteria with rounds 5 and 6 at least ``shapesd``'s
would need a seventh round, written after it, before it could ship.

**Measured**: ``soup50`` two spheres 0.9604, ood +0.047, round 5 -0.020, round 6 -0.021 (half way along the
line from ``strips16`` to ``shapes``); ``shapesm`` 0.9603, +0.046, -0.016, -0.010 (as ``shapesd``: the mixed
scene taught by ``strips16`` gave back none of the ood margin, which the generic frames take from the
diagonal edge, -0.026, and the washers, -0.008). **One more, declared before it is made**: is the trade a
capacity limit? ``shapes384``: ``shapesm``'s frames and teachers on the grown ``context384_consistent``
network (``python scripts/strips_grow.py models/strips16.pt --size context384_consistent --out
runs/init_context384.pt``; ``train --init runs/init_context384.pt``, which carries the size), 8 epochs,
two threads; the same criteria plus batch-1 latency <= 150 us.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
from scipy import ndimage

from synth.scene import Scene, load_scene

sys.path.insert(0, str(Path(__file__).resolve().parent))
import strips_product_fields as products  # a sibling script: its sensor push and dataset writer

FORCE_N = (0.5, 10.0)  # the frame's total load (the wide scene's contacts reach 10 N each)
LENGTH_MM = (0.6, 20.0)  # the smoothing's shorter correlation length (log-uniform): a speck to a palm
ASPECT = (1.0, 25.0)  # longer / shorter length (log-uniform): round to a string
COVER = (0.02, 1.0)  # share of the array's cells the shape covers (log-uniform)
RIM_SHARE = 0.3  # frames keeping only the shape's rim
RIM_CELLS = (1, 4)  # the rim's depth (cells of 0.625 mm)
RIGID_SHARE = 0.5  # flat pressure on the shape; the rest rises with the field above the cut
RAMP_SHARE = 0.3  # frames tilted by a linear ramp across the array


def shapes_scene() -> Scene:
    base = load_scene("strips16")
    return dataclasses.replace(
        base,
        name="strips16_random_shapes",
        description="the strips16 sensor under random shapes (scripts/strips_random_shapes.py)",
    )


def smooth_noise(size: int, pad: int, h_mm: float, rng: np.random.Generator) -> np.ndarray:
    """One anisotropic Gaussian-smoothed white-noise field on a (size + 2 pad) square lattice of pitch
    ``h_mm``, cropped to the centre ``size`` square (the array); unit-free."""
    full = size + 2 * pad
    length = math.exp(rng.uniform(math.log(LENGTH_MM[0]), math.log(LENGTH_MM[1])))
    aspect = math.exp(rng.uniform(math.log(ASPECT[0]), math.log(ASPECT[1])))
    angle = rng.uniform(0.0, math.pi)
    k = np.fft.fftfreq(full, d=h_mm) * 2.0 * math.pi  # rad / mm
    kr, kc = np.meshgrid(k, np.fft.rfftfreq(full, d=h_mm) * 2.0 * math.pi, indexing="ij")
    along = kr * math.cos(angle) + kc * math.sin(angle)
    across = -kr * math.sin(angle) + kc * math.cos(angle)
    # a Gaussian kernel's transform: exp(-(k l)^2 / 2) along each axis (the long axis along `angle`)
    gain = np.exp(-0.5 * ((along * length * aspect) ** 2 + (across * length) ** 2))
    white = rng.standard_normal((full, full))
    field = np.fft.irfft2(np.fft.rfft2(white) * gain, s=(full, full))
    return np.asarray(field[pad : pad + size, pad : pad + size])


def shape(size: int, h_mm: float, rng: np.random.Generator) -> np.ndarray:
    """One non-negative (size, size) pressure shape (unit-free) with a positive sum."""
    g = smooth_noise(size, size // 2, h_mm, rng)
    cover = math.exp(rng.uniform(math.log(COVER[0]), math.log(COVER[1])))
    cut = float(np.quantile(g, 1.0 - cover)) if cover < 1.0 else -np.inf
    mask = g >= cut
    if rng.uniform() < RIM_SHARE:
        depth = int(rng.integers(RIM_CELLS[0], RIM_CELLS[1] + 1))
        inner = ndimage.binary_erosion(mask, iterations=depth, border_value=1)  # (off the array: inside)
        if (mask & ~inner).any():
            mask = mask & ~inner
    if rng.uniform() < RIGID_SHARE or not np.isfinite(cut):
        p = mask.astype(np.float64)
    else:  # soft: rises from the cut with the field (a dome over each island)
        p = np.sqrt(np.clip(g - cut, 0.0, None)) * mask
    if rng.uniform() < RAMP_SHARE:
        x = (np.arange(size) + 0.5) / size - 0.5
        angle = rng.uniform(0.0, 2.0 * math.pi)
        ramp = 1.0 + rng.uniform(0.5, 2.0) * (x[:, None] * math.cos(angle) + x[None, :] * math.sin(angle))
        p = p * np.clip(ramp, 0.0, None)
    if p.sum() <= 0.0:  # nothing left on the array (a ramp to zero over a small shape): one cell
        p = np.zeros((size, size))
        p[rng.integers(size), rng.integers(size)] = 1.0
    return p


def draw(scene: Scene, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """``n`` frames: readings (B, 32) V and the intersection map (B, 16, 16) kPa."""
    return products.draw_shapes(scene, n, rng, shape, FORCE_N)


def write(n: int, seed: int, out: Path) -> Path:
    """The dataset folder (shards seeded per index, manifest last)."""
    return products.write(n, seed, out, shapes_scene(), draw)


def main(argv: list[str] | None = None) -> int:
    return products.run_cli(argv, __doc__, write)


if __name__ == "__main__":
    sys.exit(main())
