"""The strip inverse for any layout (``synth.sensors.strip_layouts``): C readings -> N x M map.

The orthogonal networks (``strips``, ``strips_general``) read N + M strip loads; other layouts add
channels that see the map along other lines (diagonal strips), with a position weight (two-ended
strips) or over part of a strip (taps). This network keeps the orthogonal network's structure and
adds what the extra channels say at every crossing:

1. :class:`LayoutLoads` inverts each channel's readout in-graph (series divider or current
   division, as ``StripSensor.invert_readings``);
2. the row and column strips' total loads (ends and sections summed) feed the row and column
   encoders, the classical normalised product and the global context (every channel's load);
3. *back-projections*: for every channel group (e.g. the +45 strips, the rows' far ends) each
   channel's load is spread over the cells it reads, giving one map per group;
4. *unrolled refinement*: :data:`REFINE_STEPS` multiplicative (MART/ISRA-like) updates of the
   classical product map against every channel, with the cell-level linear model ``L = A x`` (``A``:
   the layout's channel weights summed over layers, no cover blur): a ghost crossing that the
   diagonal strips (or the two ends' balance, or the taps) do not see loses its load. The refined
   map is a further per-crossing input, so the network starts from what the extra channels say;
5. the same axial mixing blocks and softplus head as architecture 1.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

from synth.scene import Scene
from synth.sensors.strips import StripSensor
from tactile_learn.nets.strip_blocks import SIZES, AxialBlock, StripLoads, context_mlp, strip_encoder

__all__ = ["LayoutLoads", "LayoutStripNet"]

#: the ``arch`` entry of the normalisation statistics of a layout network
ARCH = 3
#: multiplicative refinement steps unrolled in the graph
REFINE_STEPS = 4


class LayoutLoads(StripLoads):
    """Readings (V) -> channel loads, the readout inverse of ``StripSensor.invert_readings``: the
    series divider's inverse (:class:`StripLoads`) or, for current-division channels, linear."""

    linear: torch.Tensor

    def __init__(self, scene: Scene) -> None:
        super().__init__(scene)
        layout = StripSensor(scene.sensor).layout
        self.segments = torch.from_numpy(layout.segments.astype(np.float32))  # replaces the buffer
        self.register_buffer("linear", torch.from_numpy(layout.linear.astype(np.float32)))

    def forward(self, volts: torch.Tensor) -> torch.Tensor:
        series = super().forward(volts)
        current = ((volts - self.offset) / (self.gain * self.supply / 4.0)).clamp_min(0.0) * self.segments
        return self.linear * current + (1.0 - self.linear) * series


class LayoutStripNet(nn.Module):
    """Readings of any layout -> map (module docstring)."""

    to_rows: torch.Tensor
    to_cols: torch.Tensor
    spread: torch.Tensor
    system: torch.Tensor

    def __init__(self, scene: Scene, stats: dict[str, Any], size: str) -> None:
        super().__init__()
        enc, hidden, context, axial = SIZES[size]
        sensor = StripSensor(scene.sensor)
        layout = sensor.layout
        self.n_rows, self.n_cols = layout.n_rows, layout.n_cols
        self.loads = LayoutLoads(scene)
        self.load_scale = float(stats["load_scale"])
        self.pressure_scale = float(stats["pressure_scale_kpa"])
        to_rows, to_cols = layout.strip_totals
        self.register_buffer("to_rows", torch.from_numpy(to_rows.astype(np.float32)))
        self.register_buffer("to_cols", torch.from_numpy(to_cols.astype(np.float32)))
        # (C, G * N * M): channel c's share spread over its cells, in its group's map
        cells = layout.weights.sum(axis=1).reshape(layout.n_channels, -1)
        spread = np.zeros((layout.n_channels, len(layout.groups), cells.shape[1]), np.float32)
        for g, group in enumerate(layout.groups):
            rows = slice(group.start, group.stop)
            spread[rows, g] = cells[rows] > 0
        self.n_groups = len(layout.groups)
        self.register_buffer("spread", torch.from_numpy(spread.reshape(layout.n_channels, -1)))
        self.register_buffer("system", torch.from_numpy(cells.astype(np.float32)))  # (C, N*M)
        self.row_encoder = strip_encoder(enc)
        self.col_encoder = strip_encoder(enc)
        self.context = context_mlp(layout.n_channels, context, hidden)
        self.row_proj = nn.Conv1d(enc + 1, hidden, 1)
        self.col_proj = nn.Conv1d(enc + 1, hidden, 1, bias=False)
        self.cell_proj = nn.Conv2d(2 + self.n_groups, hidden, 1, bias=False)
        self.blocks = nn.Sequential(*[AxialBlock(hidden) for _ in range(axial)])
        self.head = nn.Conv2d(hidden, 1, 1)

    def forward(self, readings: torch.Tensor) -> torch.Tensor:
        loads = self.loads(readings) / self.load_scale
        rows = loads @ self.to_rows
        cols = loads @ self.to_cols
        row_feat = torch.cat([self.row_encoder(rows.unsqueeze(1)), rows.unsqueeze(1)], dim=1)
        col_feat = torch.cat([self.col_encoder(cols.unsqueeze(1)), cols.unsqueeze(1)], dim=1)
        total = 0.5 * (rows.sum(dim=1) + cols.sum(dim=1)).clamp_min(1e-3)
        product = (rows.unsqueeze(2) * cols.unsqueeze(1) / total[:, None, None]).unsqueeze(1)
        spread = (loads @ self.spread).reshape(-1, self.n_groups, self.n_rows, self.n_cols)
        refined = self.refine(product.flatten(1), loads).reshape_as(product)
        x = (
            self.row_proj(row_feat).unsqueeze(3)
            + self.col_proj(col_feat).unsqueeze(2)
            + self.context(loads)[:, :, None, None]
            + self.cell_proj(torch.cat([product, refined, spread], dim=1))
        )
        x = self.blocks(torch.relu(x))
        out = nn.functional.softplus(self.head(x).squeeze(1), beta=4.0)
        return out * self.pressure_scale

    def refine(self, x: torch.Tensor, loads: torch.Tensor) -> torch.Tensor:
        """:data:`REFINE_STEPS` updates ``x <- x * A^T L / A^T A x`` (both in normalised load units)."""
        measured = loads @ self.system  # A^T L: fixed over the steps
        for _ in range(REFINE_STEPS):
            predicted = (x @ self.system.T) @ self.system
            # 1e-4 normalised load units: a cell no channel sees keeps its value instead of 0/0
            x = x * (measured + 1e-4) / (predicted + 1e-4)
        return x
