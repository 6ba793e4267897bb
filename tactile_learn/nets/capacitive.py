"""Network for the capacitive array: calibrated cell loads (B, N, M) in N -> (B, 2, N s, M s): the
surface force on every fine pixel (N) and the contact-mask probability, at ``s = samples_per_pitch``
times the taxel resolution (CapContact's super-resolution, here from a calibrated force image).

Structure: the loads (scaled) and two coordinate channels (the array's edges matter: the cover
loses load beyond them) pass three 3 x 3 convolutions at the taxel grid; a 1 x 1 convolution and a
pixel shuffle lift the features to half the fine resolution, where the bicubic image of the loads
joins them (the network learns a correction to the classical baseline); two 3 x 3 convolutions
there, and a 1 x 1 head with a last pixel shuffle give the force (softplus) and the mask (logits;
probabilities in ``forward``) at the fine resolution. (The 3 x 3 convolutions at half resolution
cost a quarter of full-resolution ones; each half-resolution feature predicts a 2 x 2 block.)
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

from synth.scene import Scene
from tactile_learn.estimators.classical.capacitive import bicubic_matrix

__all__ = ["SIZES", "CapacitiveNet", "build_capacitive_net", "capacitive_loss", "gap_weights", "input_stats"]

#: size -> (taxel-grid channels, half-resolution channels)
SIZES: dict[str, tuple[int, int]] = {"small": (48, 24), "large": (64, 32)}


def input_stats(loads: np.ndarray, force_image: np.ndarray) -> dict[str, Any]:
    """Scales from training data: the loads' RMS over loaded cells (N) and the force per pixel's RMS
    over pixels that carry force."""
    loads = np.asarray(loads, dtype=np.float64)
    force = np.asarray(force_image, dtype=np.float64)
    loaded = loads[loads > 1e-3]
    pressed = force[force > 0]
    return {
        "load_scale_n": float(np.sqrt(np.mean(loaded**2))) if loaded.size else 1.0,
        "force_scale_n": float(np.sqrt(np.mean(pressed**2))) if pressed.size else 1e-3,
    }


class CapacitiveNet(nn.Module):
    rows_up: torch.Tensor
    cols_up: torch.Tensor
    coords: torch.Tensor

    def __init__(self, scene: Scene, stats: dict[str, Any], size: str) -> None:
        super().__init__()
        coarse, fine = SIZES[size]
        g = scene.sensor.geometry
        self.s = g.samples_per_pitch
        last = 2 if self.s % 2 == 0 else 1  # the head's own shuffle
        self.mid = self.s // last
        self.load_scale = float(stats["load_scale_n"])
        self.force_scale = float(stats["force_scale_n"])
        self.register_buffer("rows_up", torch.from_numpy(bicubic_matrix(g.n_rows, self.mid).astype(np.float32)))
        self.register_buffer("cols_up", torch.from_numpy(bicubic_matrix(g.n_cols, self.mid).astype(np.float32)))
        ys = torch.linspace(-1.0, 1.0, g.n_rows)[:, None].expand(g.n_rows, g.n_cols)
        xs = torch.linspace(-1.0, 1.0, g.n_cols)[None, :].expand(g.n_rows, g.n_cols)
        self.register_buffer("coords", torch.stack([ys, xs])[None].contiguous())
        # the first convolution over [loads, y, x], written as two so that the coordinates broadcast
        # over the batch (an ``expand`` to the batch size would fix it in the exported graph)
        self.first = nn.Conv2d(1, coarse, 3, padding=1)
        self.first_coords = nn.Conv2d(2, coarse, 3, padding=1, bias=False)
        self.coarse = nn.Sequential(
            nn.ReLU(),
            nn.Conv2d(coarse, coarse, 3, padding=1),
            nn.ReLU(),
            nn.Conv2d(coarse, coarse, 3, padding=1),
            nn.ReLU(),
            nn.Conv2d(coarse, fine * self.mid * self.mid, 1),
            nn.PixelShuffle(self.mid),
        )
        self.fine = nn.Sequential(
            nn.ReLU(),
            nn.Conv2d(fine + 1, fine, 3, padding=1),
            nn.ReLU(),
            nn.Conv2d(fine, fine, 3, padding=1),
            nn.ReLU(),
            nn.Conv2d(fine, 2 * last * last, 1),
            nn.PixelShuffle(last),
        )

    def raw(self, loads: torch.Tensor) -> torch.Tensor:
        """``(B, 2, H, W)``: force (N per pixel, non-negative) and mask logits."""
        x = loads.unsqueeze(1) / self.load_scale
        bicubic = torch.relu(self.rows_up @ x @ self.cols_up.T) / (self.mid * self.mid)
        features = self.coarse(self.first(x) + self.first_coords(self.coords))
        out = self.fine(torch.cat([features, bicubic], dim=1))
        force = nn.functional.softplus(out[:, :1], beta=4.0) * self.force_scale
        return torch.cat([force, out[:, 1:]], dim=1)

    def forward(self, loads: torch.Tensor) -> torch.Tensor:
        out = self.raw(loads)
        return torch.cat([out[:, :1], torch.sigmoid(out[:, 1:])], dim=1)


def build_capacitive_net(size: str, scene: Scene, stats: dict[str, Any]) -> CapacitiveNet:
    if size not in SIZES:
        raise ValueError(f"size {size!r} is not one of {', '.join(SIZES)}")
    return CapacitiveNet(scene, stats, size)


def gap_weights(mask: np.ndarray, weight: float = 10.0, sigma_px: float = 1.5) -> np.ndarray:
    """Per-pixel weights of the mask loss: 1, plus ``weight exp(-(d1 + d2)^2 / (2 sigma^2))`` on pixels
    outside the mask at distances ``d1 <= d2`` from the two nearest contacts (U-Net's border weights,
    Ronneberger et al. 2015): the few pixels that keep two nearby contacts apart count as much as a
    contact's whole outline."""
    from scipy import ndimage

    from tactile_learn.estimators.classical.contact_shapes import label_contacts

    mask = np.asarray(mask, dtype=bool)
    labels, counts = label_contacts(mask)
    out = np.ones(mask.shape, dtype=np.float32)
    for b in np.flatnonzero(counts >= 2):
        dist = np.sort(np.stack([ndimage.distance_transform_edt(labels[b] != c) for c in range(1, counts[b] + 1)]), 0)
        out[b] += np.where(mask[b], 0.0, weight * np.exp(-((dist[0] + dist[1]) ** 2) / (2 * sigma_px**2)))
    return out


def capacitive_loss(
    raw: torch.Tensor, force: torch.Tensor, mask: torch.Tensor, force_scale: float, weight: torch.Tensor | None = None
) -> torch.Tensor:
    """Force MSE in units of the force scale, plus the mask's binary cross-entropy (``weight``: per
    pixel, :func:`gap_weights`) and soft Dice (masks cover a few percent of the pixels: Dice keeps
    small contacts from being ignored)."""
    force_term = ((raw[:, 0] - force) / force_scale).pow(2).mean()
    logits = raw[:, 1]
    bce = nn.functional.binary_cross_entropy_with_logits(logits, mask, weight=weight)
    prob = torch.sigmoid(logits).flatten(1)
    target = mask.flatten(1)
    inter = (prob * target).sum(dim=1)
    denom = prob.sum(dim=1) + target.sum(dim=1)
    has = target.sum(dim=1) > 0
    dice = (1 - 2 * inter[has] / denom[has].clamp_min(1e-6)).mean() if bool(has.any()) else prob.sum() * 0
    return force_term + bce + dice
