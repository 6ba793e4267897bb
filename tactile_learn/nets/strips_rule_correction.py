"""A specialist for one family of shapes: the intersection rule's map, corrected by a small MLP of
the frame's strip loads. It measures how far an estimator that knows the family can get above the
rule (issue 12's smooth random field: ``scripts/strips_blob_bound.py``, docs/strips.md "How far above the
rule can a smooth field go").

``map = rule x exp(c) + a x mean(rule)`` with ``(c, a)`` per crossing from an MLP of the loads
normalised by their total and the log of the total. The MLP sees every load, so the correction can
in principle be any function of the readings; its last layer starts at zero, so an untrained
specialist answers the rule exactly and training can only add what the rule misses.
"""

from __future__ import annotations

import torch
from torch import nn

from synth.errors import ConfigError
from synth.scene import Scene
from synth.sensors.strips import StripSensor

__all__ = ["RuleCorrectionNet", "pearson_loss"]


class RuleCorrectionNet(nn.Module):
    """Input: strip loads (B, N + M) (``StripSensor.invert_readings``); output: maps (B, N, M) kPa.

    ``noise_floor`` and ``max_share`` are the intersection estimator's (loads under ``noise_floor``
    load-noise levels are zeroed, shares capped at ``max_share``): untrained, the two agree to
    float32 rounding."""

    floor: torch.Tensor  # (N + M,) the loads zeroed below it (a buffer: it follows the net's device)

    def __init__(
        self, scene: Scene, hidden: int = 512, depth: int = 3, noise_floor: float = 2.0, max_share: float = 0.95
    ) -> None:
        super().__init__()
        sensor = StripSensor(scene.sensor)
        if not sensor.layout.orthogonal:
            raise ConfigError("RuleCorrectionNet: the layout is not one row strip and one column strip per line")
        if hidden < 1 or depth < 1:
            raise ConfigError(f"RuleCorrectionNet: hidden {hidden} and depth {depth} must be at least 1")
        self.n_rows, self.n_cols = sensor.n_rows, sensor.n_cols
        self.p0 = float(sensor.law.p0_kpa)
        self.exponent = float(sensor.law.exponent)
        self.max_share = max_share
        floor = noise_floor * torch.as_tensor(sensor.load_noise(), dtype=torch.float32)
        self.register_buffer("floor", floor)
        channels = self.n_rows + self.n_cols
        layers: list[nn.Module] = []
        width = channels + 1
        for _ in range(depth):
            layers += [nn.Linear(width, hidden), nn.GELU()]
            width = hidden
        self.body = nn.Sequential(*layers)
        self.head = nn.Linear(hidden, 2 * self.n_rows * self.n_cols)
        nn.init.zeros_(self.head.weight)  # the rule, exactly, until training moves it
        nn.init.zeros_(self.head.bias)

    def rule(self, loads: torch.Tensor) -> torch.Tensor:
        """The intersection estimator's product rule (B, N, M) kPa."""
        loads = torch.where(loads > self.floor, loads, torch.zeros_like(loads))
        rows, cols = loads[:, : self.n_rows], loads[:, self.n_rows :]
        total = 0.5 * (rows.sum(1) + cols.sum(1))
        # an idle frame has T = 0: its map is zero, not 0/0
        share = rows[:, :, None] * cols[:, None, :] / total.clamp_min(1e-30)[:, None, None]
        share = share.clamp(0.0, self.max_share)
        return self.p0 * torch.expm1(-torch.log1p(-share) / self.exponent)

    def forward(self, loads: torch.Tensor) -> torch.Tensor:
        rule = self.rule(loads)
        total = 0.5 * loads.sum(1, keepdim=True)
        # the shape of the loads and, apart, their size (log: forces span a decade)
        features = torch.cat([loads / total.clamp_min(1e-6), torch.log(total.clamp_min(1e-3))], dim=1)
        c, a = self.head(self.body(features)).chunk(2, dim=1)
        flat = rule.flatten(1)
        # clamped: exp stays finite however far an early step throws the head
        out = flat * torch.exp(c.clamp(-5.0, 5.0)) + a * flat.mean(1, keepdim=True)
        return out.view(-1, self.n_rows, self.n_cols)


def pearson_loss(pred: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """1 - the mean per-frame Pearson r of maps (B, ...): the figure the suites report. Frames whose
    truth is flat (no contact: r undefined) are left out; all flat gives 0."""
    p = pred.flatten(1)
    t = truth.flatten(1)
    p = p - p.mean(1, keepdim=True)
    t = t - t.mean(1, keepdim=True)
    tt = (t * t).sum(1)
    keep = tt > 1e-12
    if not keep.any():
        return pred.sum() * 0.0
    # the 1e-12 keeps a flat prediction's gradient finite (its r is 0)
    r = (p * t).sum(1)[keep] / torch.sqrt((p * p).sum(1)[keep] * tt[keep] + 1e-12)
    return 1.0 - r.mean()
