"""An object's pressure template from its unlabelled strip readings: tomography at unknown angles (torch).

Each frame of an orthogonal strip array gives two projections of the pressure under the object: the
row loads (the field summed along x, one value per row strip) and the column loads (summed along y).
An object pressed many times, at different angles and places, so gives projections of one shape at
many angles, as in tomography, except that the angle and the place of every frame are unknown. They
are found together with the shape by alternating (hard expectation-maximisation, as single-particle
imaging does with its unknown orientations):

- **E** (:func:`best_poses`): for every frame, the angle (``angles`` steps over 360 degrees) and the
  object's centre (whole cells of the fine lattice; the row and the column centre are searched apart,
  since each projection moves with one of them only) whose projections of the current template, with
  one least-squares scale, explain the frame's loads best. Every frame is divided by its own load, so
  that a hard press and a light one count alike.
- **M** (:func:`_fit_template`): the template (``size`` x ``size`` cells of the fine lattice, in the
  object's frame; non-negative through a softplus; a little roughness penalty) fitted by Adam to every
  frame's loads at its pose.

Only the readings are read: no map, no label, nothing about the object's family. What is fitted is the
shape of the load the strips see (the cover's spreading and the piezoresistive law's saturation are in
it, averaged over the frames' forces); :mod:`tactile_learn.learn_object` renders it back through the
sensor model as a specialist's training set. Two limits, by construction: a shape and its mirror image
give different projections only through detail (the fit may settle on either when the readings cannot
tell), and parts whose loads vary from press to press are fitted at their mean.
docs/strips.md ("Learning an object from its readings") measures what a specialist built this way
reaches on round 12's objects.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from synth.errors import ConfigError, DataError
from synth.io import atomic_save_npz
from synth.sensors.strips.config import StripsConfig
from synth.sensors.strips.physics import StripSensor
from tactile_learn.object_frames import frame_loads, orthogonal_only, readable_object_frames

__all__ = [
    "ObjectTemplate",
    "TomographyConfig",
    "best_poses",
    "fit_template",
    "frame_loads",
    "readable_object_frames",
    "rotated",
]

TEMPLATE_KIND = "tactile-learn object template"


@dataclass(frozen=True)
class TomographyConfig:
    """``size``: template side in fine cells (128 at 0.625 mm: 80 mm, twice the strips16 array, so that
    objects larger than the array fit); ``angles``: angle steps over 360 degrees; ``iterations``: E/M
    rounds; ``steps``/``lr``: Adam steps and rate of every M; ``smooth``: weight of the roughness
    penalty (relative to the template's energy)."""

    size: int = 128
    angles: int = 72
    iterations: int = 20
    steps: int = 60
    lr: float = 0.05
    smooth: float = 0.02
    seed: int = 0

    def __post_init__(self) -> None:
        if not 16 <= self.size <= 512 or self.size % 2:
            raise ConfigError(f"size: expected an even number of cells in [16, 512], got {self.size}")
        if not 4 <= self.angles <= 720:
            raise ConfigError(f"angles: expected 4 to 720 steps over 360 degrees, got {self.angles}")
        if self.iterations < 1 or self.steps < 1:
            raise ConfigError(f"iterations and steps must be >= 1, got {self.iterations} and {self.steps}")
        if not (0 < self.lr <= 1 and 0 <= self.smooth <= 10):
            raise ConfigError(f"lr in (0, 1] and smooth in [0, 10] expected, got {self.lr} and {self.smooth}")


@dataclass(frozen=True)
class ObjectTemplate:
    """A fitted object: ``template`` (T, T) float32, non-negative, summing to 1 (rows y, columns x, the
    object's centre at the middle); ``centres`` (K, 2) the fine-lattice cells (row, column) where the
    fit placed each frame's centre, ``total_load`` (K,) each frame's load and ``residual`` (K,) how much
    of it the fit leaves unexplained (relative), for the K frames fitted; ``cell_mm`` the lattice's
    cell; ``scene_digest`` the sensor it was read on."""

    template: np.ndarray
    centres: np.ndarray
    total_load: np.ndarray
    residual: np.ndarray
    cell_mm: float
    scene_digest: str
    history: tuple[dict[str, float], ...] = ()

    def save(self, path: str | Path) -> Path:
        """An ``.npz`` written atomically (a template is never half written)."""
        path = Path(path)
        atomic_save_npz(
            path,
            {
                "kind": np.array(TEMPLATE_KIND),
                "template": self.template.astype(np.float32),
                "centres": self.centres.astype(np.int32),
                "total_load": self.total_load.astype(np.float64),
                "residual": self.residual.astype(np.float32),
                "cell_mm": np.array(self.cell_mm, dtype=np.float64),
                "scene_digest": np.array(self.scene_digest),
            },
        )
        return path

    @classmethod
    def load(cls, path: str | Path) -> ObjectTemplate:
        """Read and check a template file; anything missing, malformed or non-finite is refused by name."""
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        except FileNotFoundError:
            raise DataError(f"{path}: no such template file") from None
        except Exception as exc:  # a truncated or foreign file: numpy's own errors vary
            raise DataError(f"{path}: not a readable template file ({exc})") from None
        needed = ("kind", "template", "centres", "total_load", "residual", "cell_mm", "scene_digest")
        missing = [k for k in needed if k not in arrays]
        if missing or str(arrays.get("kind", "")) != TEMPLATE_KIND:
            raise DataError(f"{path}: not an object template (missing {', '.join(missing) or 'its kind'})")
        t, centres, load = arrays["template"], arrays["centres"], arrays["total_load"]
        if t.ndim != 2 or t.shape[0] != t.shape[1] or not np.isfinite(t).all() or (t < 0).any() or t.sum() <= 0:
            raise DataError(f"{path}: template must be a square, finite, non-negative, non-zero image")
        if centres.ndim != 2 or centres.shape[1] != 2 or len(centres) == 0 or len(load) != len(centres):
            raise DataError(f"{path}: centres (K, 2) and total_load (K,) must describe the same K > 0 frames")
        if not np.isfinite(load).all() or (load <= 0).any():
            raise DataError(f"{path}: total_load must be positive and finite")
        cell = float(arrays["cell_mm"])
        if not (np.isfinite(cell) and cell > 0):
            raise DataError(f"{path}: cell_mm must be positive")
        return cls(
            template=(t / t.sum()).astype(np.float32),
            centres=centres.astype(np.int64),
            total_load=load.astype(np.float64),
            residual=arrays["residual"].astype(np.float32),
            cell_mm=cell,
            scene_digest=str(arrays["scene_digest"]),
        )


def _centres(size: int, strips: int, per: int) -> np.ndarray:
    """Centre cells searched: the object's centre may lie up to an eighth of the template beyond the array's edge."""
    reach = size // 8
    return np.arange(-reach, strips * per + reach)


def _shift_matrices(size: int, strips: int, per: int, centres: np.ndarray) -> torch.Tensor:
    """(C, strips, size): template cell u of an object centred at lattice cell c falls on lattice cell
    u - size/2 + c, which belongs to strip (u - size/2 + c) // per when it is on the array."""
    u = np.arange(size)
    mats = np.zeros((len(centres), strips, size), dtype=np.float32)
    for k, c in enumerate(centres):
        cell = u - size // 2 + int(c)
        on = (cell >= 0) & (cell < strips * per)
        mats[k, cell[on] // per, u[on]] = 1.0
    return torch.from_numpy(mats)


def rotated(template: torch.Tensor, angles: torch.Tensor) -> torch.Tensor:
    """(A, T, T): the template (T, T; or (1, 1, T, T)) rotated by every angle (radians) about its centre."""
    size = template.shape[-1]
    cos, sin = torch.cos(angles), torch.sin(angles)
    zero = torch.zeros_like(cos)
    theta = torch.stack([torch.stack([cos, -sin, zero], 1), torch.stack([sin, cos, zero], 1)], 1)
    grid = F.affine_grid(theta, [len(angles), 1, size, size], align_corners=False)
    batch = template.reshape(1, 1, size, size).expand(len(angles), 1, size, size)
    return F.grid_sample(batch, grid, mode="bilinear", padding_mode="zeros", align_corners=False)[:, 0]


def _profiles(
    template: torch.Tensor, angles: torch.Tensor, rows_at: torch.Tensor, cols_at: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Row and column profiles (A, C, strips) of the rotated template at every centre."""
    g = rotated(template, angles)
    along_y, along_x = g.sum(2), g.sum(1)  # the field summed along x (rows read it) and along y
    return torch.einsum("cit,at->aci", rows_at, along_y), torch.einsum("cit,at->aci", cols_at, along_x)


@torch.no_grad()
def best_poses(
    template: torch.Tensor,
    angles: torch.Tensor,
    rows_at: torch.Tensor,
    cols_at: torch.Tensor,
    rows: torch.Tensor,
    cols: torch.Tensor,
    chunk: int = 32,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """E: every frame's best (angle index, row-centre index, column-centre index) and the share of its
    loads' energy the best pose leaves unexplained (square-rooted: a relative residual).

    For a pose, the least-squares scale ``a`` of ``min_a |r - a p|^2 + |c - a q|^2`` leaves
    ``|r|^2 + |c|^2 - (r.p + c.q)^2 / (|p|^2 + |q|^2)``: the search maximises the last term over
    angle x row centre x column centre, with ``r.p`` and ``c.q`` computed once per angle and centre."""
    qr, qc = _profiles(template, angles, rows_at, cols_at)
    nr, nc = (qr**2).sum(-1), (qc**2).sum(-1)
    n_c = rows_at.shape[0]
    found: list[list[torch.Tensor]] = [[], [], [], []]
    for lo in range(0, len(rows), chunk):
        r, c = rows[lo : lo + chunk], cols[lo : lo + chunk]
        dr = torch.einsum("bi,aci->bac", r, qr)
        dc = torch.einsum("bi,aci->bac", c, qc)
        # a negative scale is no press: such poses explain nothing (relu)
        gain = torch.relu(dr[:, :, :, None] + dc[:, :, None, :]) ** 2 / (
            nr[None, :, :, None] + nc[None, :, None, :] + 1e-12
        )
        best, idx = gain.reshape(len(r), -1).max(1)
        energy = (r**2).sum(1) + (c**2).sum(1)
        found[0].append(idx // (n_c * n_c))
        found[1].append((idx // n_c) % n_c)
        found[2].append(idx % n_c)
        found[3].append(torch.sqrt(torch.clamp(energy - best, min=0.0) / energy))
    a, y, x, res = (torch.cat(v).numpy() for v in found)
    return a, y, x, res


def _template_of(weights: torch.Tensor) -> torch.Tensor:
    g = F.softplus(weights)
    return g / g.sum()


def _fit_template(
    weights: torch.Tensor,
    angles: torch.Tensor,
    rows_at: torch.Tensor,
    cols_at: torch.Tensor,
    rows: torch.Tensor,
    cols: torch.Tensor,
    pose: tuple[np.ndarray, np.ndarray, np.ndarray],
    config: TomographyConfig,
) -> float:
    """M: Adam on the template's weights, every frame at its pose with its own least-squares scale."""
    a_idx, y_idx, x_idx = (torch.from_numpy(v.astype(np.int64)) for v in pose)
    used = torch.unique(a_idx)  # only the angles some frame sits at are rotated
    slot = torch.full((len(angles),), -1, dtype=torch.int64)
    slot[used] = torch.arange(len(used))
    energy = (rows**2).sum(1) + (cols**2).sum(1)
    opt = torch.optim.Adam([weights], lr=config.lr)
    value = 0.0
    for _ in range(config.steps):
        g = _template_of(weights)
        rot = rotated(g, angles[used])
        along_y, along_x = rot.sum(2), rot.sum(1)
        p = torch.einsum("bit,bt->bi", rows_at[y_idx], along_y[slot[a_idx]])
        q = torch.einsum("bit,bt->bi", cols_at[x_idx], along_x[slot[a_idx]])
        scale = ((rows * p).sum(1) + (cols * q).sum(1)) / ((p**2).sum(1) + (q**2).sum(1) + 1e-12)
        fit = ((rows - scale[:, None] * p) ** 2).sum(1) + ((cols - scale[:, None] * q) ** 2).sum(1)
        rough = ((g[1:] - g[:-1]) ** 2).sum() + ((g[:, 1:] - g[:, :-1]) ** 2).sum()
        loss = (fit / energy).mean() + config.smooth * rough / (g**2).sum()
        opt.zero_grad()
        loss.backward()
        opt.step()
        value = float(loss.detach())
    return value


def fit_template(
    readings: np.ndarray,
    config: StripsConfig,
    scene_digest: str,
    tomography: TomographyConfig | None = None,
    log: Callable[[str], None] | None = None,
) -> ObjectTemplate:
    """Fit an object's template to ``readings`` (B, N+M) of it (checked frames: :func:`readable_object_frames`)."""
    orthogonal_only(config)
    tomo = tomography or TomographyConfig()
    sensor = StripSensor(config)
    per = config.geometry.samples_per_pitch
    rows, cols, total = frame_loads(readings, sensor)
    torch.manual_seed(tomo.seed)
    rng = np.random.default_rng(tomo.seed)
    centres_y = _centres(tomo.size, sensor.n_rows, per)
    centres_x = _centres(tomo.size, sensor.n_cols, per)
    if len(centres_y) != len(centres_x):  # best_poses searches one grid of centres for both
        raise ConfigError("object tomography needs as many row strips as column strips")
    rows_at = _shift_matrices(tomo.size, sensor.n_rows, per, centres_y)
    cols_at = _shift_matrices(tomo.size, sensor.n_cols, per, centres_x)
    angles = torch.arange(tomo.angles, dtype=torch.float32) * (2 * math.pi / tomo.angles)
    # the start: a round blob a tenth of the template wide, roughened so that the first poses differ
    yy, xx = np.mgrid[0 : tomo.size, 0 : tomo.size] - (tomo.size - 1) / 2
    blob = np.exp(-(yy**2 + xx**2) / (2 * (tomo.size / 10) ** 2)) * (1 + 0.3 * rng.random((tomo.size, tomo.size)))
    weights = torch.tensor(np.log(np.expm1(np.maximum(blob, 1e-6))), dtype=torch.float32, requires_grad=True)
    r_t = torch.from_numpy(rows.astype(np.float32))
    c_t = torch.from_numpy(cols.astype(np.float32))
    history = []
    for it in range(tomo.iterations):
        start = time.perf_counter()
        a, y, x, res = best_poses(_template_of(weights.detach()), angles, rows_at, cols_at, r_t, c_t)
        loss = _fit_template(weights, angles, rows_at, cols_at, r_t, c_t, (a, y, x), tomo)
        history.append({"iteration": it, "residual_median": float(np.median(res)), "loss": loss})
        if log is not None:
            log(
                f"iteration {it + 1}/{tomo.iterations}: median residual {np.median(res):.4f} "
                f"({time.perf_counter() - start:.1f} s)"
            )
    template = _template_of(weights.detach())
    a, y, x, res = best_poses(template, angles, rows_at, cols_at, r_t, c_t)
    return ObjectTemplate(
        template=template.numpy().astype(np.float32),
        centres=np.stack([centres_y[y], centres_x[x]], 1),
        total_load=total,
        residual=res.astype(np.float32),
        cell_mm=config.geometry.pitch_mm / per,
        scene_digest=scene_digest,
        history=tuple(history),
    )
