"""Networks for the strip inverse: N+M readings -> N x M intersection map (kPa).

Structure that matches the physics:

1. :class:`StripLoads` inverts the readout in-graph (the same formula as the classical
   estimators), so the network starts from each strip's load, not from volts.
2. Row and column *encoders* (1-D convolutions along the strips' stacking direction) turn the
   load profiles into per-strip features: a contact's footprint spreads over neighbouring strips,
   and the profile's shape tells its size.
3. The *pair* stage builds, for every crossing (i, j), the row feature i + column feature j and
   three physics channels: the classical normalised product ``Lr_i Lc_j / T`` and the two loads
   broadcast. Per-crossing 1 x 1 convolutions decide whether a crossing is real or a ghost: a real
   contact's row and column loads agree in magnitude and footprint, a ghost's do not.
   A global context vector (an MLP over all N+M loads) is added everywhere: which rows pair with
   which columns is decided by magnitudes across the whole array.
4. Axial blocks mix every crossing with the strongest and mean features along its row and its
   column (its competitors in a ghost configuration); a softplus keeps pressure non-negative.

Normalisation lives in the module as buffers, so the exported ONNX graph maps raw volts to kPa.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

from synth.scene import Scene
from synth.sensors.strips import StripSensor
from tactile_learn.nets.strip_blocks import SIZES, AxialBlock, StripLoads, context_mlp, strip_encoder

__all__ = ["SIZES", "StripLoads", "StripNet", "build_strip_net", "input_stats", "strip_loss"]

#: weight of an intermediate map's loss (see :func:`strip_loss`)
INTERMEDIATE_WEIGHT = 0.3
# the shared blocks live in ``strip_blocks``; their old names here stay importable
_Axial = AxialBlock
_encoder = strip_encoder


def input_stats(readings: np.ndarray, pressure: np.ndarray, scene: Scene) -> dict[str, Any]:
    """Normalisation from training data: the loads' scale and the pressure's RMS (kPa), and what the
    general architecture (``strips_general``, the one new models are built with) needs."""
    from tactile_learn.nets.strips_general import general_stats

    sensor = StripSensor(scene.sensor)
    loads = sensor.invert_readings(readings.astype(np.float64))
    load_scale = float(np.sqrt(np.mean(loads**2)) + 1e-6)
    pressure_scale = float(np.sqrt(np.mean(pressure.astype(np.float64) ** 2)) + 1e-6)
    if not sensor.layout.orthogonal:  # any other layout: the layout network (strips_layout)
        from tactile_learn.nets.strips_layout import ARCH

        return {"load_scale": load_scale, "pressure_scale_kpa": pressure_scale, "arch": ARCH}
    return {
        "load_scale": load_scale,
        "pressure_scale_kpa": pressure_scale,
        **general_stats(loads, pressure, sensor.load_noise()),
    }


class StripNet(nn.Module):
    """Readings -> map, with crossing features built by broadcast sums (cheap: no N x M convolutions
    before the pair stage, and no 3 x 3 convolutions at all)."""

    def __init__(self, scene: Scene, stats: dict[str, Any], size: str) -> None:
        super().__init__()
        enc, hidden, context, axial = SIZES[size]
        g = scene.sensor.geometry
        self.n_rows, self.n_cols = g.n_rows, g.n_cols
        self.loads = StripLoads(scene)
        self.load_scale = float(stats["load_scale"])
        self.pressure_scale = float(stats["pressure_scale_kpa"])
        self.row_encoder = strip_encoder(enc)
        self.col_encoder = strip_encoder(enc)
        # global context: every strip's load at once (magnitudes decide which rows pair with which columns)
        self.context = context_mlp(g.n_rows + g.n_cols, context, hidden)
        self.row_proj = nn.Conv1d(enc + 1, hidden, 1)
        self.col_proj = nn.Conv1d(enc + 1, hidden, 1, bias=False)
        self.product_proj = nn.Conv2d(1, hidden, 1, bias=False)
        self.blocks = nn.Sequential(*[AxialBlock(hidden) for _ in range(axial)])
        self.head = nn.Conv2d(hidden, 1, 1)

    def forward(self, readings: torch.Tensor) -> torch.Tensor:
        loads = self.loads(readings) / self.load_scale
        rows = loads[:, : self.n_rows]
        cols = loads[:, self.n_rows :]
        row_feat = torch.cat([self.row_encoder(rows.unsqueeze(1)), rows.unsqueeze(1)], dim=1)  # (B, C+1, N)
        col_feat = torch.cat([self.col_encoder(cols.unsqueeze(1)), cols.unsqueeze(1)], dim=1)  # (B, C+1, M)
        total = 0.5 * (rows.sum(dim=1) + cols.sum(dim=1)).clamp_min(1e-3)
        product = (rows.unsqueeze(2) * cols.unsqueeze(1) / total[:, None, None]).unsqueeze(1)  # classical estimate
        # the convolution last, onto one full-size sum: one fused node under onnxruntime
        # (tactile_learn.onnx_fuse)
        x = self.product_proj(product) + (
            self.row_proj(row_feat).unsqueeze(3)
            + self.col_proj(col_feat).unsqueeze(2)
            + self.context(loads)[:, :, None, None]
        )
        x = self.blocks(torch.relu(x))
        out = nn.functional.softplus(self.head(x).squeeze(1), beta=4.0)
        return out * self.pressure_scale


def build_strip_net(size: str, scene: Scene, stats: dict[str, Any]) -> nn.Module:
    """The network of ``size``: architecture 2 (``strips_general``, every model trained since the
    shape library) when the statistics say so, else this module's first architecture (models
    shipped before it). ``v1_small`` / ``v1_large`` train the first architecture on purpose (the
    two-sphere specialist's recipe)."""
    if stats.get("arch", 1) == 3:
        from tactile_learn.nets.strips_layout import LayoutStripNet

        size = size.removeprefix("v1_")
        if size not in SIZES:
            raise ValueError(f"size {size!r} is not one of {', '.join(SIZES)} (a layout network)")
        return LayoutStripNet(scene, stats, size)
    if size.startswith("v1_"):
        size = size.removeprefix("v1_")
    elif stats.get("arch", 1) == 2:
        from tactile_learn.nets.strips_general import SIZES as GENERAL_SIZES
        from tactile_learn.nets.strips_general import GeneralStripNet

        if size not in GENERAL_SIZES:
            raise ValueError(f"size {size!r} is not one of {', '.join(GENERAL_SIZES)}")
        return GeneralStripNet(scene, stats, size)
    if size not in SIZES:
        raise ValueError(f"size {size!r} is not one of {', '.join(SIZES)}")
    return StripNet(scene, stats, size)


def strip_loss(
    pred: torch.Tensor | tuple[torch.Tensor, ...], target: torch.Tensor, r_weight: float = 1.0
) -> torch.Tensor:
    """MSE in units of the pressure scale, plus ``r_weight`` (1 - Pearson r) per frame: the metric
    users read (the batch's MSE is dominated by its heaviest frames, r weighs every frame alike).

    Frames with an all-zero truth contribute only their MSE (their r is undefined). A tuple of
    maps (a network's final map and its intermediate ones) adds each intermediate map's loss at
    :data:`INTERMEDIATE_WEIGHT`, so that the first estimate is itself good and the correction step
    starts from it.
    """
    if isinstance(pred, tuple):
        total = strip_loss(pred[0], target, r_weight)
        for intermediate in pred[1:]:
            total = total + INTERMEDIATE_WEIGHT * strip_loss(intermediate, target, r_weight)
        return total
    scale = target.pow(2).mean().sqrt().clamp_min(1e-6)
    mse = ((pred - target) / scale).pow(2).mean()
    p = pred.flatten(1) - pred.flatten(1).mean(dim=1, keepdim=True)
    t = target.flatten(1) - target.flatten(1).mean(dim=1, keepdim=True)
    denom = (p.pow(2).sum(dim=1) * t.pow(2).sum(dim=1)).clamp_min(1e-12).sqrt()
    valid = t.pow(2).sum(dim=1) > 1e-12
    r = (p * t).sum(dim=1) / denom
    corr = (1 - r[valid]).mean() if bool(valid.any()) else pred.sum() * 0
    return mse + r_weight * corr
