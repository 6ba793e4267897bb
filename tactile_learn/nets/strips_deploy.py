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

import copy
import math
from typing import Any

import torch
from torch import nn

from synth.errors import ModelError
from synth.scene import Scene
from tactile_learn.nets.strip_blocks import axial_pools, law_gain
from tactile_learn.nets.strips_consistent import ConsistencyStep
from tactile_learn.nets.strips_general import MAX_SHARE, GeneralStripNet, StripForward, StripResidual, law_inverse

__all__ = ["DeployedStripNet", "deploy"]


def _grouped_conv1d(a: Any, b: Any, first: bool) -> nn.Conv1d:
    """One Conv1d of two groups, rows then columns: group 0 computes ``a``, group 1 ``b`` (no
    multiplications by the zeros of a block-diagonal matrix), and each group passes its strip
    profile through unchanged as its last channel (a 1 at the kernel's centre: exact). A group's
    channels: the layer's features, then the profile; the first layer reads the profiles alone."""
    k = a.kernel_size[0]
    features = a.out_channels
    width = 1 if first else features + 1  # input channels per group
    conv = nn.Conv1d(2 * width, 2 * (features + 1), k, padding=a.padding, groups=2)
    assert conv.bias is not None
    with torch.no_grad():
        conv.weight.zero_()
        conv.bias.zero_()
        for g, trained in enumerate((a, b)):
            out = g * (features + 1)
            conv.weight[out : out + features, : trained.in_channels] = trained.weight
            conv.weight[out + features, width - 1, k // 2] = 1.0  # the profile: the group's last input
            conv.bias[out : out + features] = trained.bias if trained.bias is not None else 0.0
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
        rows, cols = axial_pools(x)
        # the pooled terms first: their full-size sum is what the 1 x 1 convolution adds onto
        # (one fused node under onnxruntime, tactile_learn.onnx_fuse)
        return torch.relu(self.own(x) + (self.along_rows(rows) + self.along_cols(cols)))


class DeployedStripNet(nn.Module):
    """``GeneralStripNet`` (no correction step) rearranged for export; outputs the map, its readings
    residual and the readings' balance (``StripResidual``). A network with the consistency step
    (``nets.strips_consistent``) takes it on the map; the residual is then the one of the map
    before the step, as ``GeneralStripNetWithResidual`` reports it."""

    total_weights: torch.Tensor
    total_bias: torch.Tensor
    diff_weights: torch.Tensor
    half_weights: torch.Tensor
    sums: torch.Tensor
    stress: torch.Tensor
    noise_weights: torch.Tensor
    numerator: torch.Tensor

    def __init__(self, net: GeneralStripNet, scene: Scene) -> None:
        super().__init__()
        if net.correct:
            raise ModelError("the deployed form covers networks without the correction step")
        n, m = net.n_rows, net.n_cols
        if n != m:
            raise ModelError("the deployed form covers square arrays (rows and columns share its convolutions)")
        self.n_rows, self.n_cols = n, m
        self._readout(net)
        self.total_floor = net.total_floor
        cross: Any = net.crossings
        enc = int(cross.row_encoder[0].out_channels)
        hidden = int(cross.row_proj.out_channels)
        layers: list[nn.Module] = []
        for k, (ra, ca) in enumerate(zip(cross.row_encoder, cross.col_encoder, strict=True)):
            if isinstance(ra, nn.Conv1d) and isinstance(ca, nn.Conv1d):
                # rows and columns as two groups of one convolution; every layer carries the profiles
                # through to the projections (non-negative: the ReLUs keep them): no Concat joins them
                layers += [_grouped_conv1d(ra, ca, first=k == 0), nn.ReLU()]
        self.encoder = nn.Sequential(*layers)
        self._projections(net, enc, hidden)
        self.hidden = hidden
        self.blocks = nn.Sequential(*[_DeployedAxial(b) for b in list(net.blocks)])
        self._head(net, hidden)
        self.consistent = net.consistency is not None
        self._checks(scene)

    def _readout(self, net: GeneralStripNet) -> None:
        """loads = clip(c0 - c1 / clip(v / gain + (v_unloaded - offset / gain), lo, hi), 0, 1) * segments,
        with the clip moved onto v, the affine map into one shift and the (uniform, square array)
        segment count into the constants: clip(C0 - C1 / (clip(v, lo', hi') + shift), 0, S)."""
        loads = net.loads
        scale, shift = 1.0 / loads.gain, loads.v_unloaded - loads.offset / loads.gain
        lo, hi = 1e-9 * loads.supply, loads.supply * (1 - 1e-9)
        self.v_lo, self.v_hi = (lo - shift) / scale, (hi - shift) / scale  # scale > 0: bounds keep their order
        self.v_shift = shift / scale
        segments = float(loads.segments[0])  # n == m: every strip has the same number of segments
        self.c0 = segments * (1.0 + loads.reference / loads.r0)
        self.segments = segments
        # a 0-d tensor, not a Python number: the exporter writes one Div instead of Reciprocal and Mul
        self.register_buffer("numerator", torch.tensor(segments * loads.reference * loads.supply / loads.r0 / scale))

    def _projections(self, net: GeneralStripNet, enc: int, hidden: int) -> None:
        """The strip projections, the physics channels and the context MLP, folded."""
        cross: Any = net.crossings
        # physics channels 2 and 3 (the broadcast row and column loads) join the strip projections'
        # raw-profile weight; channels 0 and 1 (outer product, minimum) stay per crossing
        phys = cross.physics_proj.weight[:, :, 0, 0]  # (H, 4)
        row_w = cross.row_proj.weight.clone()  # (H, enc + 1, 1)
        col_w = cross.col_proj.weight.clone()
        with torch.no_grad():
            row_w[:, enc, 0] += phys[:, 2]
            col_w[:, enc, 0] += phys[:, 3]
        # two projections of the encoder's [enc_row, raw_row, enc_col, raw_col] (B, 2 enc + 2, N) ->
        # (B, H, N) each: the row projection reads the row group, the column projection the other
        self.project_rows = nn.Conv1d(2 * enc + 2, hidden, 1)
        self.project_cols = nn.Conv1d(2 * enc + 2, hidden, 1, bias=False)
        with torch.no_grad():
            self.project_rows.weight.zero_()
            self.project_cols.weight.zero_()
            self.project_rows.weight[:, : enc + 1] = row_w
            self.project_cols.weight[:, enc + 1 :] = col_w
            assert self.project_rows.bias is not None
            self.project_rows.bias.copy_(cross.row_proj.bias)
        self.physics = nn.Conv2d(2, hidden, 1, bias=False)
        with torch.no_grad():
            self.physics.weight.copy_(cross.physics_proj.weight[:, :2])
        # the context reads log(T / T_ref): the reference moves into the first layer's bias
        ctx: Any = net.context
        first = nn.Linear(ctx[0].in_features, ctx[0].out_features)
        with torch.no_grad():
            first.weight.copy_(ctx[0].weight)
            first.bias.copy_(ctx[0].bias - ctx[0].weight[:, -1] * math.log(net.total_ref))
        self.context = nn.Sequential(first, ctx[1], ctx[2], ctx[3], ctx[4])

    def _head(self, net: GeneralStripNet, hidden: int) -> None:
        """exp(clip(h0)) * (p0 / n) * product + softplus(4 h1) / 4 * (pressure scale / total_ref): the
        slope and softplus' beta folded into two 1 x 1 heads (two convolutions: no channel gathers)."""
        slope = net.p0 / net.exponent
        trained: Any = net.head
        self.head_scale = nn.Conv2d(hidden, 1, 1)
        self.head_mass = nn.Conv2d(hidden, 1, 1)
        with torch.no_grad():
            for i, conv in enumerate((self.head_scale, self.head_mass)):
                assert conv.bias is not None
                conv.weight.copy_(trained.weight[i : i + 1])
                conv.bias.copy_(trained.bias[i : i + 1])
            assert self.head_scale.bias is not None and self.head_mass.bias is not None
            self.head_scale.bias += math.log(slope)
            self.head_mass.weight *= 4.0
            self.head_mass.bias *= 4.0
        self.clip = (-20.0 + math.log(slope), 4.0 + math.log(slope))
        self.slope = slope
        self.law_base = net.law_base
        self.p0, self.exponent = net.p0, net.exponent
        self.unit = net.pressure_scale / net.total_ref / 4.0

    def _checks(self, scene: Scene) -> None:
        """The forward model and the checks of ``StripResidual`` as matrix products over the loads."""
        n = self.n_rows
        forward = StripForward(scene)
        residual = StripResidual(scene)
        self.p0_forward, self.exponent_forward = forward.p0, forward.exponent
        strips = forward.sums.shape[1]
        self.step: ConsistencyStep | None = None
        if self.consistent:  # the step's separable operators give the model loads too
            self.step = ConsistencyStep(forward)
        else:
            self.register_buffer("stress", forward.stress.clone())
            self.register_buffer("sums", forward.sums.clone())
        # residual = sqrt(mean(((model - measured) / noise)^2)) = || (model - measured) w ||_2 with
        # w = 1 / (noise sqrt(N+M)); the difference first, as StripResidual takes it (model and
        # measured loads are large in noise units and close: their difference loses the least)
        self.register_buffer("noise_weights", residual.inverse_noise / math.sqrt(strips))
        # balance = |rows - cols| / ((rows + cols) / 2 + floor); the frame total = the same half sum
        is_row = (torch.arange(strips) < n).to(torch.float32)
        self.register_buffer("diff_weights", 2.0 * is_row - 1.0)
        self.register_buffer("half_weights", torch.full((strips,), 0.5))
        # the frame total as one Gemm (weights and the floor as its bias), not a MatMul and an Add
        self.register_buffer("total_weights", torch.full((1, strips), 0.5))
        self.register_buffer("total_bias", torch.tensor([self.total_floor], dtype=torch.float32))
        self.balance_floor = residual.floor

    def forward(self, readings: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        n = self.n_rows
        loads = (self.c0 - self.numerator / (readings.clamp(self.v_lo, self.v_hi) + self.v_shift)).clamp(
            0.0, self.segments
        )
        total = nn.functional.linear(loads, self.total_weights, self.total_bias)  # (B, 1)
        shape = loads / total
        context = self.context(torch.cat([shape, torch.log(total)], dim=1))  # (B, H)
        profiles = shape.reshape(-1, 2, n)  # rows and columns as the two channels of one sequence
        features = self.encoder(profiles)  # the encoder's features and the profiles carried through
        row_terms = self.project_rows(features) + context.unsqueeze(2)  # (B, H, N)
        col_terms = self.project_cols(features)
        rows = shape[:, :n].reshape(-1, 1, n, 1)
        cols = shape[:, n:].reshape(-1, 1, 1, n)
        product = rows * cols  # (B, 1, N, M)
        physics = torch.cat([product, torch.minimum(rows, cols)], dim=1)
        x = torch.relu(self.physics(physics) + (row_terms.unsqueeze(3) + col_terms.unsqueeze(2)))
        x = self.blocks(x)
        base = product  # the classical estimate / (slope * total): the linear base
        if self.law_base:  # the law's inverse of the share (exponent 1: three nodes, no power)
            share = (product * total.reshape(-1, 1, 1, 1)).clamp(0.0, MAX_SHARE)
            if self.exponent == 1.0:
                base = product / (1.0 - share)
            else:
                base = law_inverse(share, self.p0, self.exponent) / (self.slope * total.reshape(-1, 1, 1, 1))
        mass = nn.functional.softplus(self.head_mass(x))  # exported with its threshold: no overflow
        learned = torch.exp(self.head_scale(x).clamp(*self.clip)) * base + mass * self.unit
        flat = (learned.reshape(-1, n * n)) * total  # (B, N*M)
        if self.consistent:
            return self._consistent(flat, loads)
        return (flat.reshape(-1, n, n), *self._consistency(flat, loads, total))

    def _consistent(self, flat: torch.Tensor, loads: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The map after ``ConsistencyStep`` (its separable form), the residual of the map before it
        (the step's model loads: no second pass through the forward model) and the balance."""
        assert self.step is not None
        maps, model = self.step.step(flat.reshape(-1, self.n_rows, self.n_cols), loads)
        residual = torch.linalg.vector_norm((model - loads) * self.noise_weights, dim=1)
        balance = (loads @ self.diff_weights).abs() / (loads @ self.half_weights + self.balance_floor)
        return maps, residual, balance

    def _consistency(
        self, flat: torch.Tensor, loads: torch.Tensor, total: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``StripForward`` and ``StripResidual`` on the flat map (non-negative by construction, so
        no clamp before the stress; the truncated kernel's -1e-6-sized stress far from any load
        moves a gain by 1e-8 of p0, so none after it either)."""
        stress = flat @ self.stress
        gain = law_gain(stress, self.p0_forward, self.exponent_forward)
        residual = torch.linalg.vector_norm((gain @ self.sums - loads) * self.noise_weights, dim=1)
        balance = (loads @ self.diff_weights).abs() / (loads @ self.half_weights + self.balance_floor)
        return residual, balance


def deploy(net: GeneralStripNet, scene: Scene, probe: torch.Tensor, tolerance: float = 1e-4) -> DeployedStripNet:
    """The deployed form of ``net``, checked against it on ``probe`` readings (B, N+M).

    Both run in float64 for the check: the rearrangement is exact algebra, and in float32 the
    readout's rounding (a few 1e-6 of a strip's load, whichever order of operations) moves the map
    by ~1e-4 of its range through a trained network, which would hide a real folding mistake of
    that size or fail a correct one."""
    from tactile_learn.nets.strips_general import GeneralStripNetWithResidual

    deployed = DeployedStripNet(net, scene).eval()
    check = copy.deepcopy(deployed).double()
    reference = GeneralStripNetWithResidual(copy.deepcopy(net), scene).double().eval()
    with torch.inference_mode():
        wide = probe.double()
        for got, want in zip(check(wide), reference(wide), strict=True):
            # maps in kPa: relative to their range; the dimensionless checks (O(1)): at least absolute
            span = max(float(want.max() - want.min()), 1.0)
            if float((got - want).abs().max()) > tolerance * span:
                raise ModelError(
                    f"the deployed network differs from the trained one by {float((got - want).abs().max()):.3g} "
                    f"(> {tolerance} of the output range {span:.3g})"
                )
    return deployed
