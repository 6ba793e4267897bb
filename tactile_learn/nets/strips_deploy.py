"""The exported form of a trained general strip network: the same function, fewer graph nodes.

At batch 1 onnxruntime spends most of a small network's time starting nodes, not computing, so
the trained :class:`~tactile_learn.nets.strips_general.GeneralStripNet` (without its correction
step) is rearranged before export, with its weights folded, never retrained:

- the readout inverse is one affine map, a reciprocal and a clip (the training module spells out
  the divider, the resistance and the segment share step by step);
- the frame's shape and total come from one sum and one division of all N+M loads;
- rows and columns run through one set of convolutions with block-diagonal weights (the row and
  column profiles are the two channels of one sequence: square arrays only; other arrays export the
  training module as it is);
- the broadcast load channels of the physics stage are folded into the strip projections (a
  1 x 1 convolution of a broadcast row profile is a row term), the context into the row term;
- each mixing block adds its input through its own 1 x 1 weights (``W + I``);
- the output scales (the intersection estimate's slope, the learned part's unit, softplus' beta)
  are folded into the head, and the frame's total multiplies the map once.

:func:`deploy` checks the rearranged module against the original on probe inputs and refuses a
difference above ``tolerance`` of the output range.
"""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import nn

from synth.errors import ModelError
from synth.scene import Scene
from tactile_learn.nets.strips_general import MAX_SHARE, GeneralStripNet, StripForward, StripResidual, law_inverse

__all__ = ["DeployedStripNet", "deploy"]


def _block_diagonal_conv1d(a: Any, b: Any, groups_in: tuple[int, int]) -> nn.Conv1d:
    """One Conv1d computing ``a`` on the first ``groups_in[0]`` input channels and ``b`` on the
    next ``groups_in[1]``, outputs stacked (zeros across)."""
    ia, ib = groups_in
    oa, ob = a.out_channels, b.out_channels
    k = a.kernel_size[0]
    conv = nn.Conv1d(ia + ib, oa + ob, k, padding=a.padding)
    with torch.no_grad():
        conv.weight.zero_()
        conv.weight[:oa, :ia] = a.weight
        conv.weight[oa:, ia:] = b.weight
        assert conv.bias is not None
        conv.bias[:oa] = a.bias if a.bias is not None else 0.0
        conv.bias[oa:] = b.bias if b.bias is not None else 0.0
    return conv


class _DeployedAxial(nn.Module):
    """:class:`~tactile_learn.nets.strip_blocks.AxialBlock` with its input added through its own weights
    (``W + I``: one node fewer). (Channels-last matrix products instead of the 1 x 1 convolutions
    were measured slower under onnxruntime.)"""

    def __init__(self, block: Any) -> None:
        super().__init__()
        channels = int(block.own.in_channels)
        self.own = nn.Conv2d(channels, channels, 1)
        with torch.no_grad():
            self.own.weight.copy_(block.own.weight + torch.eye(channels)[:, :, None, None])
            assert self.own.bias is not None
            self.own.bias.copy_(block.own.bias)
        self.along_rows = block.along_rows
        self.along_cols = block.along_cols

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        rows = torch.cat([x.amax(dim=3, keepdim=True), x.mean(dim=3, keepdim=True)], dim=1)
        cols = torch.cat([x.amax(dim=2, keepdim=True), x.mean(dim=2, keepdim=True)], dim=1)
        return torch.relu(self.own(x) + self.along_rows(rows) + self.along_cols(cols))


class DeployedStripNet(nn.Module):
    """``GeneralStripNet`` (no correction step) rearranged for export; outputs the map, its readings
    residual and the readings' balance (``StripResidual``)."""

    segments: torch.Tensor

    def __init__(self, net: GeneralStripNet, scene: Scene) -> None:
        super().__init__()
        if net.correct:
            raise ModelError("the deployed form covers networks without the correction step")
        n, m = net.n_rows, net.n_cols
        self.n_rows, self.n_cols = n, m
        loads = net.loads
        # loads = clip(c0 - c1 / clip(v / gain + (v_unloaded - offset / gain), lo, hi), 0, 1) * segments
        self.scale_v = 1.0 / loads.gain
        self.shift_v = loads.v_unloaded - loads.offset / loads.gain
        self.lo, self.hi = 1e-9 * loads.supply, loads.supply * (1 - 1e-9)
        self.c0 = 1.0 + loads.reference / loads.r0
        self.c1 = loads.reference * loads.supply / loads.r0
        self.register_buffer("segments", loads.segments.clone())
        self.total_floor = net.total_floor
        self.log_ref = math.log(net.total_ref)
        if n != m:
            raise ModelError("the deployed form covers square arrays (rows and columns share its convolutions)")
        cross: Any = net.crossings
        enc = int(cross.row_encoder[0].out_channels)
        hidden = int(cross.row_proj.out_channels)
        layers: list[nn.Module] = []
        for k, (ra, ca) in enumerate(zip(cross.row_encoder, cross.col_encoder, strict=True)):
            if isinstance(ra, nn.Conv1d) and isinstance(ca, nn.Conv1d):
                width = (1, 1) if k == 0 else (enc, enc)
                layers += [_block_diagonal_conv1d(ra, ca, width), nn.ReLU()]
        self.encoder = nn.Sequential(*layers)
        # physics channels 2 and 3 (the broadcast row and column loads) join the strip projections'
        # raw-profile weight; channels 0 and 1 (outer product, minimum) stay per crossing
        phys = cross.physics_proj.weight[:, :, 0, 0]  # (H, 4)
        row_w = cross.row_proj.weight.clone()  # (H, enc + 1, 1)
        col_w = cross.col_proj.weight.clone()
        with torch.no_grad():
            row_w[:, enc, 0] += phys[:, 2]
            col_w[:, enc, 0] += phys[:, 3]
        # one projection of [enc_row, enc_col, raw_row, raw_col] (B, 2 enc + 2, N) -> (B, 2H, N)
        self.project = nn.Conv1d(2 * enc + 2, 2 * hidden, 1)
        with torch.no_grad():
            self.project.weight.zero_()
            self.project.weight[:hidden, :enc] = row_w[:, :enc]
            self.project.weight[hidden:, enc : 2 * enc] = col_w[:, :enc]
            self.project.weight[:hidden, 2 * enc] = row_w[:, enc]
            self.project.weight[hidden:, 2 * enc + 1] = col_w[:, enc]
            assert self.project.bias is not None
            self.project.bias.zero_()
            self.project.bias[:hidden] = cross.row_proj.bias
        self.physics = nn.Conv2d(2, hidden, 1, bias=False)
        with torch.no_grad():
            self.physics.weight.copy_(cross.physics_proj.weight[:, :2])
        # the context MLP's last layer writes the row half of the projection (zeros for columns)
        ctx: Any = net.context
        last = ctx[4]
        widened = nn.Linear(last.in_features, 2 * hidden)
        with torch.no_grad():
            widened.weight.zero_()
            widened.bias.zero_()
            widened.weight[:hidden] = last.weight
            widened.bias[:hidden] = last.bias
        self.context = nn.Sequential(ctx[0], ctx[1], ctx[2], ctx[3], widened)
        self.hidden = hidden
        self.blocks = nn.Sequential(*[_DeployedAxial(b) for b in list(net.blocks)])
        # head: exp(clip(h0)) * (p0 / n) * product + softplus(4 h1) / 4 * (pressure scale / total_ref)
        head = nn.Conv2d(hidden, 2, 1)
        slope = net.p0 / net.exponent
        trained: Any = net.head
        with torch.no_grad():
            head.weight.copy_(trained.weight)
            assert head.bias is not None
            head.bias.copy_(trained.bias)
            head.bias[0] += math.log(slope)
            head.weight[1] *= 4.0
            head.bias[1] *= 4.0
        self.head = head
        self.clip = (-20.0 + math.log(slope), 4.0 + math.log(slope))
        self.slope = slope
        self.law_base = net.law_base
        self.p0, self.exponent = net.p0, net.exponent
        self.unit = net.pressure_scale / net.total_ref / 4.0
        self.forward_model = StripForward(scene)
        self.residual = StripResidual(scene)

    def forward(self, readings: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        n, h = self.n_rows, self.hidden
        divider = (readings * self.scale_v + self.shift_v).clamp(self.lo, self.hi)
        loads = (self.c0 - self.c1 / divider).clamp(0.0, 1.0) * self.segments
        total = loads.sum(dim=1, keepdim=True) * 0.5 + self.total_floor  # (B, 1)
        shape = loads / total
        context = self.context(torch.cat([shape, torch.log(total) - self.log_ref], dim=1))  # (B, 2H)
        rows, cols = shape[:, :n], shape[:, n:]
        profiles = shape.reshape(-1, 2, n)  # rows and columns as the two channels of one sequence
        features = torch.cat([self.encoder(profiles), profiles], dim=1)
        terms = self.project(features) + context.unsqueeze(2)  # (B, 2H, N)
        product = rows.unsqueeze(2) * cols.unsqueeze(1)  # (B, N, M)
        physics = torch.stack([product, torch.minimum(rows.unsqueeze(2), cols.unsqueeze(1))], dim=1)
        x = torch.relu(terms[:, :h].unsqueeze(3) + terms[:, h:].unsqueeze(2) + self.physics(physics))
        head = self.head(self.blocks(x))
        base = product  # the classical estimate / (slope * total): the linear base
        if self.law_base:  # the law's inverse of the share (exponent 1: three nodes, no power)
            share = (product * total.unsqueeze(2)).clamp(0.0, MAX_SHARE)
            if self.exponent == 1.0:
                base = product / (1.0 - share)
            else:
                base = law_inverse(share, self.p0, self.exponent) / (self.slope * total.unsqueeze(2))
        learned = torch.exp(head[:, 0].clamp(*self.clip)) * base + nn.functional.softplus(head[:, 1]) * self.unit
        pressure = learned * total.unsqueeze(2)
        return (pressure, *self.residual(self.forward_model(pressure), loads))


def deploy(net: GeneralStripNet, scene: Scene, probe: torch.Tensor, tolerance: float = 1e-4) -> DeployedStripNet:
    """The deployed form of ``net``, checked against it on ``probe`` readings (B, N+M)."""
    from tactile_learn.nets.strips_general import GeneralStripNetWithResidual

    deployed = DeployedStripNet(net, scene).eval()
    reference = GeneralStripNetWithResidual(net, scene).eval()
    with torch.inference_mode():
        for got, want in zip(deployed(probe), reference(probe), strict=True):
            # maps in kPa: relative to their range; the dimensionless checks (O(1)): at least absolute
            span = max(float(want.max() - want.min()), 1.0)
            if float((got - want).abs().max()) > tolerance * span:
                raise ModelError(
                    f"the deployed network differs from the trained one by {float((got - want).abs().max()):.3g} "
                    f"(> {tolerance} of the output range {span:.3g})"
                )
    return deployed
