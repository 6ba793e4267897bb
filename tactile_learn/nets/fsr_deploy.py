"""The FSR network as exported: :class:`~tactile_learn.nets.fsr.FsrNet`'s function in fewer ONNX nodes.

At batch 1 every onnxruntime node has a fixed cost (~0.5 us, whatever it computes): the graph
exported from :class:`FsrNet` has 36 nodes (28 once onnxruntime fuses each SiLU), 14 of them
slices, scalings and concatenations around the network's five outputs and 9 for the features.
:class:`LeanFsrNet` computes the same function in 26 (22 fused):

- the features' standardisation ``(x - mean) / std`` is folded into the first layer's weights
  (``W / std``, ``b - W mean / std``);
- the outputs' scalings (``x, y`` by the film's half size, the log force by its standard deviation
  plus its mean) are folded into the last layer's rows;
- the five raw outputs are split once (position, log force, two logits) instead of sliced twice;
- the probabilities are capped at 1 (one node more than the network has: onnxruntime's Sigmoid
  gave 1 + 1 ulp for a large logit).

The folded weights are formed in float64 and rounded once; the exported graph's outputs agree with
:class:`FsrNet`'s to float32 rounding (the export's parity check; tests). Training, the loss and the
checkpoints keep :class:`FsrNet`: this module only changes what is written to ONNX.
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

    def __init__(self, net: FsrNet) -> None:
        super().__init__()
        linears = [m for m in net.mlp if isinstance(m, nn.Linear)]
        if len(linears) < 2 or len(net.mlp) != 2 * len(linears) - 1:
            raise ValueError("LeanFsrNet expects FsrNet's MLP: Linear, SiLU, ..., Linear")
        features = net.features
        self.levels = float(features.levels)
        self.low = 0.5 / self.levels
        self.eps = _EPS_CODES / self.levels
        mean, std = features.mean.double(), features.std.double()
        first = linears[0]
        w0 = first.weight.double() / std[None, :]
        b0 = first.bias.double() - w0 @ mean
        last = linears[-1]
        scale = torch.tensor(
            [float(net.xy_scale), float(net.xy_scale), float(net.logf_std), 1.0, 1.0], dtype=torch.float64
        )
        shift = torch.tensor([0.0, 0.0, float(net.logf_mean), 0.0, 0.0], dtype=torch.float64)
        w_out = last.weight.double() * scale[:, None]
        b_out = last.bias.double() * scale + shift
        hidden = [_folded_linear(m.weight.double(), m.bias.double()) for m in linears[1:-1]]
        layers: list[nn.Module] = [_folded_linear(w0, b0), nn.SiLU()]
        for layer in hidden:
            layers += [layer, nn.SiLU()]
        layers.append(_folded_linear(w_out, b_out))
        self.mlp = nn.Sequential(*layers)

    def forward(self, readings: torch.Tensor) -> torch.Tensor:
        # the features of FsrFeatures, without the standardisation (folded into the first layer)
        v = ((readings + 0.5) / self.levels).clamp(self.low, 1.0 - self.low)  # 1 - v >= half a code
        x = torch.log(v / (1.0 - v) + self.eps)
        xy, log_force, logits = self.mlp(x).split([2, 1, 2], dim=1)
        # as FsrNet.forward: the exponent clamped so that a wild output cannot overflow float32;
        # onnxruntime's Sigmoid can round a large logit to 1 + 1 ulp: the probabilities are capped at 1
        probabilities = torch.sigmoid(logits).clamp(max=1.0)
        return torch.cat([xy, torch.exp(log_force.clamp(-30.0, 60.0)), probabilities], dim=1)
