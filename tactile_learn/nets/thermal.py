"""Network for the thermal fingertip: one pixel's temperature window -> class probabilities.

Input (B, W) raw temperatures (degC), the window ending "now" with the contact onset somewhere
inside (or none). Inside the graph:

1. **Invariances by construction.** The baseline (mean of the first ``BASE`` samples, always
   before contact in a right-aligned window of ``window_s`` with contacts up to ``window_s - 0.2``
   s old) is subtracted, so the absolute temperature (ambient, the sensor's set point) carries no
   weight; the drop is scaled by the training set's typical swing (a buffer).
2. **Two views of the curve** as channels: the scaled drop, and the drop divided by its own peak
   magnitude (the *shape*, independent of the unknown object temperature), plus the log peak
   magnitude as a scalar (the amplitude, which the object temperature competes with).
3. A small 1-D CNN (stride-2 stages, GELU) keeps where along the window things happen (the onset
   is not at a fixed sample: the network sees onsets everywhere during training and learns to
   read the curve relative to it), then an MLP gives the logits.

``forward`` returns softmax probabilities (what ``Estimator.predict`` returns); ``logits`` is what
the loss sees. Only Conv1d, Linear, GELU, mean/amax/abs/log/softmax: ONNX-exportable (opset 18).
"""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from synth.scene import Scene

__all__ = ["BASE", "SIZES", "ThermalNet", "build_thermal_net", "thermal_loss"]

#: samples averaged for the baseline
BASE = 8
#: size -> (channels, stages, hidden width, a second convolution per stage)
SIZES: dict[str, tuple[int, int, int, bool]] = {
    "tiny": (16, 4, 64, False),
    "small": (24, 4, 96, False),
    "medium": (24, 4, 96, True),
    "large": (48, 4, 192, True),
}
#: floor of the peak magnitude (K) in the shape channel: keeps the division finite on flat curves
_AMP_FLOOR_K = 0.05


class ThermalNet(nn.Module):
    """Temperatures (B, W) or (B, S, W) (S sensor channels: heated, passive) -> probabilities
    (B, K + 1); see the module docstring."""

    scale: torch.Tensor

    def __init__(self, window: int, n_classes: int, scale_k: float | list[float], size: str) -> None:
        super().__init__()
        channels, stages, hidden, double = SIZES[size]
        scales = [float(scale_k)] if isinstance(scale_k, (int, float)) else [float(v) for v in scale_k]
        self.sensors = len(scales)
        # one scale per sensor channel; a single-channel net keeps the seed's scalar buffer
        self.register_buffer("scale", torch.tensor(scales[0] if self.sensors == 1 else scales))
        layers: list[nn.Module] = [nn.Conv1d(2 * self.sensors, channels, 5, padding=2), nn.GELU()]
        length = window
        for _ in range(stages):
            layers += [nn.Conv1d(channels, channels, 5, padding=2, stride=2), nn.GELU()]
            if double:
                layers += [nn.Conv1d(channels, channels, 3, padding=1), nn.GELU()]
            length = (length - 1) // 2 + 1
        self.conv = nn.Sequential(*layers)
        # scalars: each channel's log peak change, and each other channel's baseline minus the heated one
        scalars = self.sensors + (self.sensors - 1)
        self.head = nn.Sequential(
            nn.Linear(channels * length + scalars, hidden),
            nn.GELU(),
            nn.Linear(hidden, hidden),
            nn.GELU(),
            nn.Linear(hidden, n_classes),
        )

    def logits(self, x: torch.Tensor) -> torch.Tensor:
        if self.sensors == 1:
            base = x[:, :BASE].mean(dim=1, keepdim=True)
            drop = (x - base) / self.scale  # scale >= 0.1 K (fit_stats)
            amp = drop.abs().amax(dim=1, keepdim=True)
            shape = drop / (amp + _AMP_FLOOR_K / self.scale)
            h = self.conv(torch.stack([drop, shape], dim=1))
            log_amp = torch.log(amp * self.scale + _AMP_FLOOR_K)  # argument >= 0.05 K
            return self.head(torch.cat([h.flatten(1), log_amp], dim=1))
        scale = self.scale.view(1, -1, 1)
        base = x[:, :, :BASE].mean(dim=2, keepdim=True)  # (B, S, 1)
        drop = (x - base) / scale
        amp = drop.abs().amax(dim=2, keepdim=True)
        shape = drop / (amp + _AMP_FLOOR_K / scale)
        h = self.conv(torch.cat([drop, shape], dim=1))
        log_amp = torch.log(amp * scale + _AMP_FLOOR_K).flatten(1)  # (B, S)
        # how far apart the channels start (a heated sensor above a passive one at ambient): the
        # object's unknown temperature is shared, so this difference is physics, not an offset
        gap = (base[:, 1:, 0] - base[:, :1, 0]) / 10.0
        return self.head(torch.cat([h.flatten(1), log_amp, gap], dim=1))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.softmax(self.logits(x), dim=1)


def build_thermal_net(size: str, scene: Scene, stats: dict[str, Any]) -> ThermalNet:
    if size not in SIZES:
        raise ValueError(f"size {size!r} is not one of {', '.join(SIZES)}")
    scale = stats.get("channel_scale_k", stats["scale_k"])
    return ThermalNet(
        int(stats["window"]),
        len(stats["classes"]),
        scale if len(stats.get("channels", [1])) > 1 else float(stats["scale_k"]),
        size,
    )


def thermal_loss(logits: torch.Tensor, labels: torch.Tensor) -> torch.Tensor:
    """Cross-entropy with a little label smoothing (confusable materials stay calibrated)."""
    return nn.functional.cross_entropy(logits, labels.long(), label_smoothing=0.01)
