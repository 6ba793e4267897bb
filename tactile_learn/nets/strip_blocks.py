"""Building blocks shared by the strip networks (``strips``: architecture 1, ``strips_general``:
architecture 2, ``strips_layout``: architecture 3), in a module of their own so that the networks
import them from below and not from each other (``strips`` dispatches to the other two).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from synth.scene import Scene
from synth.sensors.strips import StripSensor

__all__ = ["SIZES", "AxialBlock", "StripLoads", "axial_pools", "context_mlp", "strip_encoder"]

#: size -> (strip encoder channels, crossing channels, context width, mixing blocks) of
#: architectures 1 and 3
SIZES: dict[str, tuple[int, int, int, int]] = {"small": (24, 16, 256, 2), "large": (32, 32, 256, 3)}


class StripLoads(nn.Module):
    """Readings (V) -> per-strip loads, the readout inverse of ``StripSensor.invert_readings``."""

    segments: torch.Tensor

    def __init__(self, scene: Scene) -> None:
        super().__init__()
        c = scene.sensor.readout
        piezo = scene.sensor.piezo
        g = scene.sensor.geometry
        sensor = StripSensor(scene.sensor)
        self.offset = float(c.offset_v)
        self.gain = float(c.amplifier_gain)
        self.v_unloaded = float(sensor.readout.v_unloaded)
        self.supply = float(c.supply_v)
        self.reference = float(c.reference_ohm)
        self.r0 = float(piezo.strip_resistance_ohm)
        segments = np.concatenate([np.full(g.n_rows, g.n_cols), np.full(g.n_cols, g.n_rows)]).astype(np.float32)
        self.register_buffer("segments", torch.from_numpy(segments))
        # the divider voltage v_unloaded + (volts - offset) / gain, clamped to (0, supply) as the
        # numpy inverse clamps it (outside, it is not physical), with the clamp moved onto the
        # readings (gain > 0 keeps the bounds' order) and 1 / gain into the numerator below:
        # ``clamp(volts, lo, hi) + shift`` is the divider voltage times the gain
        self.shift = self.gain * self.v_unloaded - self.offset
        self.volts_lo = self.gain * 1e-9 * self.supply - self.shift
        self.volts_hi = self.gain * self.supply * (1 - 1e-9) - self.shift
        # the segment's conductance share 1 - R / r0, R = reference (supply / divider - 1)
        self.share_at_infinity = 1.0 + self.reference / self.r0
        self.share_numerator = self.reference * self.supply / self.r0 * self.gain

    def forward(self, volts: torch.Tensor) -> torch.Tensor:
        # the same function as the readout's formula step by step, in six graph nodes instead of twelve
        divider = volts.clamp(self.volts_lo, self.volts_hi) + self.shift
        return (self.share_at_infinity - self.share_numerator / divider).clamp(0.0, 1.0) * self.segments


class AxialBlock(nn.Module):
    """Mixes every crossing with the strongest and the mean features along its row and its column.

    A ghost at (i1, j2) competes with the real contacts (i1, j1) and (i2, j2), which share its row
    and its column: pooling along both axes lets each crossing see its competitors however far
    apart they are. The 1 x 1 weights act on the pooled (N or M long) features *before* they are
    broadcast, which is the same function as mixing the broadcast copies at a fraction of the cost.
    (Dense or depthwise 3 x 3 convolutions were tried: several times slower to train on a CPU and
    no more accurate.)
    """

    def __init__(self, channels: int) -> None:
        super().__init__()
        self.own = nn.Conv2d(channels, channels, 1)
        self.along_rows = nn.Conv2d(2 * channels, channels, 1, bias=False)  # pooled over j: (B, C, N, 1)
        self.along_cols = nn.Conv2d(2 * channels, channels, 1, bias=False)  # pooled over i: (B, C, 1, M)
        self.act = nn.ReLU()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        rows, cols = axial_pools(x)
        # summed so that the 1 x 1 convolution adds onto one full-size tensor: the same function, and
        # one fused node under onnxruntime (tactile_learn.onnx_fuse) instead of a Conv, Add and ReLU
        return self.act(self.own(x) + (x + (self.along_rows(rows) + self.along_cols(cols))))


def axial_pools(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The strongest and the mean features along each row (B, 2C, N, 1) and each column (B, 2C, 1, M).

    The column mean is an average pool over the whole column: the same mean, but onnxruntime's
    ``ReduceMean`` over the middle axis is its slow, strided case (batch 1: 6.6 us against 3.6 for
    ``AveragePool``; batch 1024: 3.8 against 0.9 us per frame of 24 x 16 x 16 features); over the
    last axis ``ReduceMean`` is the faster one (3.8 against 12.2 us), so rows keep it
    (``scripts/onnx_op_bench.py``, docs/speed.md)."""
    rows = torch.cat([x.amax(dim=3, keepdim=True), x.mean(dim=3, keepdim=True)], dim=1)
    cols = torch.cat([x.amax(dim=2, keepdim=True), nn.functional.avg_pool2d(x, (x.shape[2], 1))], dim=1)
    return rows, cols


def strip_encoder(channels: int) -> nn.Sequential:
    """Per-strip features from the load profile around each strip (receptive field 13 strips).
    Per strip, not per crossing: capacity here is cheap."""
    return nn.Sequential(
        nn.Conv1d(1, channels, 5, padding=2),
        nn.ReLU(),
        nn.Conv1d(channels, channels, 5, padding=2),
        nn.ReLU(),
        nn.Conv1d(channels, channels, 5, padding=2),
        nn.ReLU(),
    )


def context_mlp(inputs: int, width: int, out: int) -> nn.Sequential:
    """The global context: an MLP over every strip's (or channel's) load at once."""
    return nn.Sequential(
        nn.Linear(inputs, width),
        nn.ReLU(),
        nn.Linear(width, width),
        nn.ReLU(),
        nn.Linear(width, out),
    )


def law_gain(stress: torch.Tensor, p0: float, exponent: float) -> torch.Tensor:
    """The piezoresistive law's conductance gain of a segment under ``stress`` (kPa):
    ``1 - (1 + s / p0)^-n``; at ``n = 1`` as ``s / (s + p0)``, without the cancellation (and no
    power node in an exported graph)."""
    if exponent == 1.0:
        return stress / (stress + p0)
    return 1.0 - torch.pow(1.0 + stress / p0, -exponent)
