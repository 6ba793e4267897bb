"""The FSR network as exported: :class:`~tactile_learn.nets.fsr.FsrNet`'s function in fewer ONNX nodes.

At batch 1 every onnxruntime node has a fixed cost (~0.5 us, whatever it computes): the graph
exported from :class:`FsrNet` has 36 nodes (28 once onnxruntime fuses each SiLU), 14 of them
slices, scalings and concatenations around the network's five outputs and 9 for the features.
:class:`LeanFsrNet` computes the same function in 21 (17 fused; the MLP alone is 12 of them):

- features (3 nodes instead of 9): the code is clamped to ``[0, L - 1]`` (the feature's clamp of
  ``v = (c + 1/2) / L`` to half a code from either end), then one Gemm gives the numerator and the
  denominator of ``G R + eps = (c + 1/2) / (L - 1/2 - c) + eps``, both affine in ``c`` and
  ``>= 1/2``, and one Log both logarithms; their difference, the features' standardisation
  ``(x - mean) / std`` and the first layer are one Gemm (weights ``[W / std, -W / std]``, bias
  ``b - W mean / std``);
- outputs (5 nodes instead of 6): the last layer's rows give ``x, y`` (scaled by the film's half
  size), ``-log F`` (its standard deviation and mean folded in) and the two negated logits; one
  clamped Exp, ``+ (0, 0, 0, 1, 1)`` and a Reciprocal give ``F = 1 / exp(-log F)`` and
  ``p = 1 / (1 + exp(-z))`` (never above 1: onnxruntime's Sigmoid gave 1 + 1 ulp for a large
  logit), and a Where keeps ``x, y`` as they are.

The folded weights are formed in float64 and rounded once; the exported graph's outputs agree with
:class:`FsrNet`'s to float32 rounding (the export's parity check; tests). The clamp of the exponent
to ``[-60, 30]`` is FsrNet's clamp of ``log F`` to ``[-30, 60]``; on the logits it moves a
probability below ``sigmoid(-30) ~ 1e-13`` up to that value, nothing else. Training, the loss and
the checkpoints keep :class:`FsrNet`: this module only changes what is written to ONNX.
"""

from __future__ import annotations

import torch
from torch import nn

from tactile_learn.nets.fsr import _EPS_CODES, FsrNet

__all__ = ["LeanFsrNet"]


def _folded_linear(weight: torch.Tensor, bias: torch.Tensor) -> nn.Linear:
    """A float32 ``nn.Linear`` with the (float64) ``weight`` and ``bias``, rounded once."""
    layer = nn.Linear(weight.shape[1], weight.shape[0])
    with torch.no_grad():
        layer.weight.copy_(weight.to(torch.float32))
        layer.bias.copy_(bias.to(torch.float32))
    return layer


class LeanFsrNet(nn.Module):
    """Readings (B, 6) -> estimate (B, 5), as :meth:`FsrNet.forward` (module docstring)."""

    out_shift: torch.Tensor
    position: torch.Tensor

    def __init__(self, net: FsrNet) -> None:
        super().__init__()
        linears = [m for m in net.mlp if isinstance(m, nn.Linear)]
        if len(linears) < 2 or len(net.mlp) != 2 * len(linears) - 1:
            raise ValueError("LeanFsrNet expects FsrNet's MLP: Linear, SiLU, ..., Linear")
        features = net.features
        levels = float(features.levels)
        self.top_code = levels - 1.0  # the clamp of v to [half a code, 1 - half a code], on the code
        self.features = _divider_terms(levels, _EPS_CODES / levels)
        mean, std = features.mean.double(), features.std.double()
        first = linears[0]
        w0 = first.weight.double() / std[None, :]
        b0 = first.bias.double() - w0 @ mean
        last = linears[-1]
        # x, y scaled by the film's half size; the log force by its std plus its mean, and negated
        # with the two logits: the graph's exponential then serves all three (module docstring)
        scale = torch.tensor(
            [float(net.xy_scale), float(net.xy_scale), -float(net.logf_std), -1.0, -1.0], dtype=torch.float64
        )
        shift = torch.tensor([0.0, 0.0, -float(net.logf_mean), 0.0, 0.0], dtype=torch.float64)
        w_out = last.weight.double() * scale[:, None]
        b_out = last.bias.double() * scale + shift
        hidden = [_folded_linear(m.weight.double(), m.bias.double()) for m in linears[1:-1]]
        # log G = log(numerator) - log(denominator): the difference is the first layer's
        layers: list[nn.Module] = [_folded_linear(torch.cat([w0, -w0], dim=1), b0), nn.SiLU()]
        for layer in hidden:
            layers += [layer, nn.SiLU()]
        layers.append(_folded_linear(w_out, b_out))
        self.mlp = nn.Sequential(*layers)
        # F = 1 / exp(-log F), p = 1 / (1 + exp(-z)): the constant 0 or 1 after the exponential
        self.register_buffer("out_shift", torch.tensor([0.0, 0.0, 0.0, 1.0, 1.0]))
        self.register_buffer("position", torch.tensor([True, True, False, False, False]))

    def forward(self, readings: torch.Tensor) -> torch.Tensor:
        # FsrFeatures without its standardisation (folded into the first layer): on the clamped
        # code c, G R + eps = (c + 1/2) / (L - 1/2 - c) + eps = numerator / denominator, both affine
        # in c and >= 1/2 (one Gemm gives both, side by side)
        terms = self.features(readings.clamp(0.0, self.top_code))
        u = self.mlp(torch.log(terms))
        # u = (x, y, -log F, -z_contact, -z_inside); the exponent clamped as FsrNet clamps log F to
        # [-30, 60] (finite in float32): for the logits that holds p within 1e-13 of the sigmoid
        # below z = -30 and gives exactly 1 above z = 60, where the sigmoid rounds to 1 too
        probabilities_and_force = torch.reciprocal(torch.exp(u.clamp(-60.0, 30.0)) + self.out_shift)
        return torch.where(self.position, u, probabilities_and_force)


def _divider_terms(levels: float, eps: float) -> nn.Linear:
    """Codes (B, 6) -> (numerator, denominator) (B, 12) of ``G R + eps`` (:class:`LeanFsrNet`):
    ``(1 - eps) c + 1/2 + eps (L - 1/2)`` and ``L - 1/2 - c``."""
    eye = torch.eye(6, dtype=torch.float64)
    weight = torch.cat([(1.0 - eps) * eye, -eye], dim=0)
    bias = torch.cat([torch.full((6,), 0.5 + eps * (levels - 0.5)), torch.full((6,), levels - 0.5)]).double()
    return _folded_linear(weight, bias)
