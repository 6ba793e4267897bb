"""The general strip inverse (architecture 2): N+M readings -> N x M map for any contact shape.

Built on the structure of the problem, cheap at batch 1:

1. **Loads, then shape and magnitude apart.** The readout is inverted in-graph to each strip's
   load (:class:`~tactile_learn.nets.strip_blocks.StripLoads`); the loads are divided by the frame's
   total load ``T`` (plus a floor at the noise level, so an empty frame stays empty), and the
   network sees the *shape* of the profiles and ``log T`` separately. The output shape is scaled
   back by ``T``: a shape learned at 2 N is the same shape at 6 N, and only the piezoresistive
   nonlinearity (through ``log T``) is left to learn about magnitude.
2. **Separable features.** 1-D convolutions encode every row and column strip's neighbourhood
   (footprint, blur); a crossing ``(i, j)`` gets row feature ``i`` + column feature ``j`` + a global
   context (an MLP over all loads: which rows pair with which columns) + three physics channels:
   the outer-product image ``Lr_i Lc_j / T`` (the classical intersection estimate), ``min(Lr_i,
   Lc_j)`` (a crossing cannot carry more than both its strips) and the broadcast loads.
3. **Axial mixing** (:class:`~tactile_learn.nets.strip_blocks.AxialBlock`): each crossing meets the strongest
   and mean features along its row and its column, where its ghost competitors sit.
4. **One correction step through the forward model** (``correct``): the first map is pushed through
   the sensor's forward model (:class:`StripForward`, the same cover kernel and piezoresistive law as
   the simulator, cell-constant pressure); the per-strip load residual is encoded like the loads and
   added to every crossing's features, and one more axial block and head correct the map. The
   forward model's output also gives the readings residual of the final map
   (:meth:`GeneralStripNet.with_residual`), which the runtime uses to flag frames unlike the training
   data (``tactile_learn.strips_guard``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

from synth.scene import Scene
from synth.sensors.strips import StripSensor
from tactile_learn.nets.strip_blocks import AxialBlock, StripLoads, law_gain, strip_encoder
from tactile_learn.nets.strips_consistent import ConsistencyStep

__all__ = ["ARCH", "CONSISTENT_SIZES", "SIZES", "GeneralStripNet", "StripForward", "StripResidual", "law_inverse"]

#: architecture number stored in the normalisation statistics (the first architecture has none)
ARCH = 2
#: the base map's largest crossing share (``Lr Lc / T`` as a fraction of a segment's conductance):
#: the piezoresistive law's inverse diverges at 1 (one noisy frame of the classical rule reads
#: 10^4 kPa there); at 0.9 it reads 9 p0 (900 kPa), above any pressure the training scenes make
MAX_SHARE = 0.9
#: size -> (strip encoder channels, crossing channels, context width, mixing blocks, correction step)
SIZES: dict[str, tuple[int, int, int, int, bool]] = {
    "small": (24, 16, 192, 2, False),
    "large": (32, 32, 256, 3, False),
    # the small network with one correction step through the forward model: measured about as
    # accurate for the same training, at 2.5 times the latency (docs/strips.md), so not the default
    "corrected": (24, 16, 192, 2, True),
    # the fast one (issue 15's small model): half the crossing channels, one mixing block
    "tiny": (16, 8, 96, 1, False),
    # the small network with a third mixing block, grown from a trained small one (scripts/strips_grow.py)
    "deep": (24, 16, 192, 3, False),
    # the small network with 24 crossing channels, widened from a trained small one
    # (scripts/strips_grow.py): about 15 % slower at batch 1 (onnxruntime's per-node cost stays)
    "wide": (24, 24, 192, 2, False),
}
# the same networks on the classical estimate itself (the law's inverse, ``base`` below)
SIZES |= {f"{name}_law": spec for name, spec in SIZES.items() if name != "corrected"}
#: sizes whose map takes one ISRA step through the forward model (``nets.strips_consistent``); the
#: step has no weights: the wide network's weights load into ``wide_consistent`` as they are
SIZES["wide_consistent"] = SIZES["wide"]
# larger networks with the step, grown from a trained ``wide_consistent`` one (scripts/strips_grow.py)
# to test whether the trade between lines and large flat contacts is a capacity limit (docs/strips.md,
# "More capacity"): 28, 32 or 40 crossing channels, a third mixing block, or a wider global context
# (per frame, not per crossing: the cheapest capacity at batch 1)
SIZES |= {
    "wide28_consistent": (24, 28, 192, 2, False),
    "wide32_consistent": (24, 32, 192, 2, False),
    "wide40_consistent": (24, 40, 192, 2, False),
    "deep_wide_consistent": (24, 24, 192, 3, False),
    "context384_consistent": (24, 24, 384, 2, False),
}
CONSISTENT_SIZES = frozenset(name for name in SIZES if name.endswith("_consistent"))


class StripForward(nn.Module):
    """Cell map (kPa, (B, N, M)) -> strip loads (B, N+M): the in-graph twin of
    ``tactile_learn.strips_consistency.StripConsistency.model_loads`` (cell-constant pressure, unit
    gains; see that module for the approximation).

    Two matrix products (few graph nodes, cheap at batch 1): the cell map to the stress on every row
    and column segment at once, then, after the piezoresistive law, the segments' sums per strip.
    """

    stress: torch.Tensor
    sums: torch.Tensor

    def __init__(self, scene: Scene) -> None:
        super().__init__()
        sensor = StripSensor(scene.sensor)
        k_row, k_col = sensor.array.cell_stress_operators()
        n, m = sensor.n_rows, sensor.n_cols
        self.n_cells = n * m
        self.register_buffer("stress", torch.from_numpy(np.concatenate([k_row.T, k_col.T], axis=1).astype(np.float32)))
        sums = np.zeros((2 * n * m, n + m), dtype=np.float32)
        cells = np.arange(n * m)
        sums[cells, cells // m] = 1.0  # row segment (i, j) belongs to row strip i
        sums[n * m + cells, n + cells % m] = 1.0  # column segment (i, j) to column strip j
        self.register_buffer("sums", torch.from_numpy(sums))
        self.p0 = float(scene.sensor.piezo.p0_kpa)
        self.exponent = float(scene.sensor.piezo.exponent)

    def forward(self, maps: torch.Tensor) -> torch.Tensor:
        x = maps.reshape(maps.shape[0], self.n_cells).clamp_min(0.0)
        # the truncated kernel can leave -1e-6-sized stress far from any load: clamped
        return law_gain((x @ self.stress).clamp_min(0.0), self.p0, self.exponent) @ self.sums


class StripResidual(nn.Module):
    """The in-graph checks of ``tactile_learn.strips_consistency``: ``residual_sigma`` of a map's
    model loads against the measured loads (RMS in units of each strip's load noise), and the
    map-free ``balance`` of the measured row and column totals."""

    inverse_noise: torch.Tensor

    def __init__(self, scene: Scene, noise_floor: float = 3.0) -> None:
        super().__init__()
        sensor = StripSensor(scene.sensor)
        noise = sensor.load_noise()
        self.n_rows = sensor.n_rows
        self.register_buffer("inverse_noise", torch.from_numpy((1.0 / noise).astype(np.float32)))
        self.floor = float(noise_floor * np.sqrt(np.sum(noise**2)))

    def forward(self, model_loads: torch.Tensor, measured: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        residual = ((model_loads - measured) * self.inverse_noise).pow(2).mean(dim=1).sqrt()
        rows = measured[:, : self.n_rows].sum(dim=1)
        cols = measured[:, self.n_rows :].sum(dim=1)
        return residual, (rows - cols).abs() / (0.5 * (rows + cols) + self.floor)


def _zero_conv(channels: int, out: int) -> nn.Conv2d:
    """A 1 x 1 head that starts at zero, but for the added mass's bias: -1 (softplus 0.005 units,
    still with a gradient), so that an untrained network answers the classical estimate."""
    conv = nn.Conv2d(channels, out, 1)
    bias = torch.zeros(out)
    bias[1:] = -1.0
    with torch.no_grad():
        conv.weight.zero_()
        conv.bias = nn.Parameter(bias)
    return conv


class _Crossings(nn.Module):
    """Per-strip profiles -> crossing features (B, C, N, M) by broadcast sums."""

    def __init__(self, enc: int, hidden: int, physics: int) -> None:
        super().__init__()
        self.row_encoder = strip_encoder(enc)
        self.col_encoder = strip_encoder(enc)
        self.row_proj = nn.Conv1d(enc + 1, hidden, 1)
        self.col_proj = nn.Conv1d(enc + 1, hidden, 1, bias=False)
        self.physics_proj = nn.Conv2d(physics, hidden, 1, bias=False) if physics else None

    def forward(self, rows: torch.Tensor, cols: torch.Tensor, physics: torch.Tensor | None = None) -> torch.Tensor:
        row_feat = torch.cat([self.row_encoder(rows.unsqueeze(1)), rows.unsqueeze(1)], dim=1)
        col_feat = torch.cat([self.col_encoder(cols.unsqueeze(1)), cols.unsqueeze(1)], dim=1)
        x = self.row_proj(row_feat).unsqueeze(3) + self.col_proj(col_feat).unsqueeze(2)
        if self.physics_proj is not None and physics is not None:
            x = x + self.physics_proj(physics)
        return x


class GeneralStripNet(nn.Module):
    """Readings (V) -> intersection map (kPa); see the module docstring."""

    def __init__(self, scene: Scene, stats: dict[str, Any], size: str) -> None:
        super().__init__()
        enc, hidden, context, blocks, correct = SIZES[size]
        g = scene.sensor.geometry
        self.n_rows, self.n_cols = g.n_rows, g.n_cols
        self.loads = StripLoads(scene)
        self.load_scale = float(stats["load_scale"])
        self.pressure_scale = float(stats["pressure_scale_kpa"])
        # the frame's total load is floored at this (a few noise levels): an empty frame stays empty
        self.total_floor = float(stats["total_floor"])
        # the typical total, so that log T and the output scale are O(1)
        self.total_ref = float(stats["total_ref"])
        self.crossings = _Crossings(enc, hidden, physics=4)
        self.context = nn.Sequential(
            nn.Linear(g.n_rows + g.n_cols + 1, context),
            nn.ReLU(),
            nn.Linear(context, context),
            nn.ReLU(),
            nn.Linear(context, hidden),
        )
        self.blocks = nn.Sequential(*[AxialBlock(hidden) for _ in range(blocks)])
        self.head = _zero_conv(hidden, 2)
        self.p0 = float(scene.sensor.piezo.p0_kpa)
        self.exponent = float(scene.sensor.piezo.exponent)
        # sizes ``*_law``: the base map is the classical intersection estimate itself (the
        # piezoresistive law's inverse of the normalised product), so a head at zero answers what the
        # classical rule answers; the others: the law's small-load slope (see _intersection)
        self.law_base = size.endswith("_law")
        self.correct = correct
        if correct:
            self.forward_model = StripForward(scene)
            self.residual_crossings = _Crossings(enc // 2, hidden, physics=0)
            self.refine = AxialBlock(hidden)
            self.refine_head = _zero_conv(hidden, 2)
        self.consistency: nn.Module | None = None
        if size in CONSISTENT_SIZES:
            self.consistency = ConsistencyStep(StripForward(scene))

    def _outputs(self, readings: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None, torch.Tensor]:
        """(final map, first map or None, measured loads), maps in kPa; with the consistency step the
        first map is the network's, before the step."""
        loads = self.loads(readings)
        rows, cols = loads[:, : self.n_rows], loads[:, self.n_rows :]
        total = 0.5 * (rows.sum(dim=1) + cols.sum(dim=1)) + self.total_floor  # (B,)
        rows_n, cols_n = rows / total[:, None], cols / total[:, None]
        magnitude = torch.log(total / self.total_ref)
        physics = torch.stack(
            [
                rows_n.unsqueeze(2) * cols_n.unsqueeze(1),  # the outer-product image
                torch.minimum(rows_n.unsqueeze(2), cols_n.unsqueeze(1)),
                rows_n.unsqueeze(2).expand(-1, -1, self.n_cols),
                cols_n.unsqueeze(1).expand(-1, self.n_rows, -1),
            ],
            dim=1,
        )
        context = self.context(torch.cat([rows_n, cols_n, magnitude.unsqueeze(1)], dim=1))
        x = self.crossings(rows_n, cols_n, physics) + context[:, :, None, None]
        x = self.blocks(torch.relu(x))
        # the frame's total load in units of the typical one sets the scale of the learned part
        unit = self.pressure_scale * (total / self.total_ref)[:, None, None]
        classical = self._intersection(rows, cols, total)
        first = self._map(self.head(x), classical, unit)
        if self.consistency is not None:
            return self.consistency(first, loads), first, loads
        if not self.correct:
            return first, None, loads
        # one correction step: what the first map leaves unexplained, strip by strip
        unexplained = (loads - self.forward_model(first)) / total[:, None]
        x = x + self.residual_crossings(unexplained[:, : self.n_rows], unexplained[:, self.n_rows :])
        final = self._map(self.head(x) + self.refine_head(self.refine(x)), classical, unit)
        return final, first, loads

    def _intersection(self, rows: torch.Tensor, cols: torch.Tensor, total: torch.Tensor) -> torch.Tensor:
        """The classical intersection estimate (kPa) from the normalised product ``Lr Lc / T``:
        through the piezoresistive law's inverse (sizes ``*_law``, shares clamped at
        :data:`MAX_SHARE`), or at the law's small-load slope ``p0 / n`` (the law's nonlinearity is then
        left to the learned rescaling). Measured on the ood suite: docs/strips.md, strips Pareto section."""
        share = rows.unsqueeze(2) * cols.unsqueeze(1) / total[:, None, None]
        if self.law_base:
            return law_inverse(share, self.p0, self.exponent)
        return share * (self.p0 / self.exponent)

    @staticmethod
    def _map(head: torch.Tensor, classical: torch.Tensor, unit: torch.Tensor) -> torch.Tensor:
        """The map from the head's two channels: the classical estimate rescaled crossing by crossing
        (ghosts suppressed, blur undone) plus non-negative mass where it has none. The head starts
        at zero, so an untrained network answers the classical estimate and learns corrections."""
        scale = torch.exp(head[:, 0].clamp(-20.0, 4.0))  # clamped: exp cannot overflow early in training
        return classical * scale + nn.functional.softplus(head[:, 1], beta=4.0) * unit

    def forward(self, readings: torch.Tensor) -> torch.Tensor:
        return self._outputs(readings)[0]

    def train_outputs(self, readings: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """The final map and, with the correction step, the first (the loss supervises both); with
        the consistency step the final map alone (the network learns what the step cannot fix)."""
        final, first, _ = self._outputs(readings)
        return (final,) if first is None or self.consistency is not None else (final, first)


class GeneralStripNetWithResidual(nn.Module):
    """The exported graph: the map, its readings residual and the readings' balance per frame."""

    def __init__(self, net: GeneralStripNet, scene: Scene) -> None:
        super().__init__()
        self.net = net
        self.forward_model = net.forward_model if net.correct else StripForward(scene)
        self.residual = StripResidual(scene)

    def forward(self, readings: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        final, first, loads = self.net._outputs(readings)
        # with the consistency step: the residual of the network's map before it (the step's own
        # model loads, no second pass through the forward model; the flags keep their meaning)
        checked = first if self.net.consistency is not None and first is not None else final
        return (final, *self.residual(self.forward_model(checked), loads))


def law_inverse(share: torch.Tensor, p0: float, exponent: float) -> torch.Tensor:
    """Stress (kPa) of a conductance share, the inverse of the piezoresistive law
    ``f = 1 - (1 + s / p0)^-n`` (``synth``'s ``stress_from_gain``), share clamped to
    [0, :data:`MAX_SHARE`]."""
    share = share.clamp(0.0, MAX_SHARE)
    if exponent == 1.0:
        return p0 * share / (1.0 - share)  # exact for n = 1, no power node
    return p0 * (torch.pow(1.0 - share, -1.0 / exponent) - 1.0)


def general_stats(loads: np.ndarray, pressure: np.ndarray, load_noise: np.ndarray) -> dict[str, Any]:
    """Normalisation of architecture 2 from training loads (B, N+M) and maps."""
    n_rows = pressure.shape[1]
    total = 0.5 * (loads[:, :n_rows].sum(axis=1) + loads[:, n_rows:].sum(axis=1))
    floor = 3.0 * float(np.sqrt(np.sum(load_noise**2)))  # three noise levels of the whole frame
    loaded = total > floor
    return {
        "arch": ARCH,
        "total_floor": floor,
        "total_ref": float(np.median(total[loaded])) if loaded.any() else 1.0,
    }
