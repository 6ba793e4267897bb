"""Network for the FSR film: six ADC codes -> (x, y, force, p_contact, p_inside).

1. :class:`FsrFeatures` inverts the divider in-graph: code -> ``G R = v / (1 - v)`` (the
   conductance in units of the divider's), then ``log(G R + eps)``, standardised with buffers.
   The log makes the FSR's resistance ~ 1/F law additive (log G = log gain + log F + log kernel),
   so a film's unknown part gains become additive offsets.
2. A small MLP (SiLU) maps the six features to five raw outputs.
3. :meth:`FsrNet.forward` turns them into the task's prediction format: ``x_mm, y_mm`` (scaled by
   the film's half size), ``force_n = exp(.)`` (log-force standardised), ``p_contact`` and
   ``p_inside`` (sigmoids). :meth:`FsrNet.raw` returns the raw outputs (logits) for the loss.

Everything is plain ONNX-exportable arithmetic; normalisation constants are buffers, so the
exported graph maps raw ADC codes to the estimate.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

from synth.scene import Scene
from synth.sensors import fsr

__all__ = ["SIZES", "FsrFeatures", "FsrNet", "build_fsr_net", "fsr_loss", "input_stats"]

#: size -> (hidden width, hidden layers)
SIZES: dict[str, tuple[int, int]] = {"small": (128, 3), "large": (256, 4)}
#: added to G R before the log: about one ADC code's worth, keeps the log finite at code 0
_EPS_CODES = 1.0


def _log_conductance(readings: np.ndarray, adc_bits: int) -> np.ndarray:
    levels = 2.0**adc_bits
    v = np.clip((readings.astype(np.float64) + 0.5) / levels, 0.5 / levels, 1.0 - 0.5 / levels)
    return np.log(v / (1.0 - v) + _EPS_CODES / levels)  # 1 - v >= half a code; argument > 0


def input_stats(readings: np.ndarray, force_n: np.ndarray, scene: Scene) -> dict[str, Any]:
    """Feature mean/std and log-force mean/std (contact frames) from training arrays."""
    config: fsr.FsrConfig = scene.sensor
    feats = _log_conductance(np.asarray(readings), config.readout.adc_bits)
    force = np.asarray(force_n, dtype=np.float64).reshape(-1)
    logf = np.log(force[force > 0]) if (force > 0).any() else np.zeros(1)
    return {
        "feature_mean": feats.mean(axis=0).tolist(),
        "feature_std": (feats.std(axis=0) + 1e-3).tolist(),
        "log_force_mean": float(logf.mean()),
        "log_force_std": float(logf.std() + 1e-3),
        "xy_scale_mm": float(config.layout.size_mm / 2.0),
    }


class FsrFeatures(nn.Module):
    """ADC codes -> standardised log divider conductances."""

    levels: torch.Tensor
    mean: torch.Tensor
    std: torch.Tensor

    def __init__(self, adc_bits: int, mean: list[float], std: list[float]) -> None:
        super().__init__()
        self.register_buffer("levels", torch.tensor(float(2**adc_bits)))
        self.register_buffer("mean", torch.tensor(mean, dtype=torch.float32))
        self.register_buffer("std", torch.tensor(std, dtype=torch.float32))

    def forward(self, readings: torch.Tensor) -> torch.Tensor:
        lo = 0.5 / self.levels
        v = ((readings + 0.5) / self.levels).clamp(lo, 1.0 - lo)  # keeps 1 - v >= half a code
        x = torch.log(v / (1.0 - v) + _EPS_CODES / self.levels)
        return (x - self.mean) / self.std  # std >= 1e-3


class FsrNet(nn.Module):
    """Readings (B, 6) -> estimate (B, 5); see the module docstring."""

    xy_scale: torch.Tensor
    logf_mean: torch.Tensor
    logf_std: torch.Tensor

    def __init__(self, scene: Scene, stats: dict[str, Any], size: str) -> None:
        super().__init__()
        width, depth = SIZES[size]
        config: fsr.FsrConfig = scene.sensor
        self.features = FsrFeatures(config.readout.adc_bits, stats["feature_mean"], stats["feature_std"])
        layers: list[nn.Module] = []
        n_in = fsr.N_SENSORS
        for _ in range(depth):
            layers += [nn.Linear(n_in, width), nn.SiLU()]
            n_in = width
        layers.append(nn.Linear(n_in, 5))
        self.mlp = nn.Sequential(*layers)
        self.register_buffer("xy_scale", torch.tensor(float(stats["xy_scale_mm"])))
        self.register_buffer("logf_mean", torch.tensor(float(stats["log_force_mean"])))
        self.register_buffer("logf_std", torch.tensor(float(stats["log_force_std"])))

    def raw(self, readings: torch.Tensor) -> torch.Tensor:
        """(B, 5): x_mm, y_mm, natural-log force (N), contact logit, inside logit (what the loss sees)."""
        h = self.mlp(self.features(readings))
        xy = h[:, 0:2] * self.xy_scale
        logf = h[:, 2:3] * self.logf_std + self.logf_mean
        return torch.cat([xy, logf, h[:, 3:5]], dim=1)

    def forward(self, readings: torch.Tensor) -> torch.Tensor:
        r = self.raw(readings)
        # clamp the exponent: a wild output must not overflow float32 (exp(60) ~ 1e26 is finite)
        force = torch.exp(r[:, 2:3].clamp(-30.0, 60.0))
        return torch.cat([r[:, 0:2], force, torch.sigmoid(r[:, 3:5])], dim=1)


def build_fsr_net(size: str, scene: Scene, stats: dict[str, Any]) -> FsrNet:
    if size not in SIZES:
        raise ValueError(f"size {size!r} is not one of {', '.join(SIZES)}")
    return FsrNet(scene, stats, size)


#: Huber widths: 0.3 mm (L1 beyond, so unlocalisable far contacts do not dominate) and 2 % in force
XY_DELTA_MM = 0.3
LOGF_DELTA = 0.02
#: weights of the terms (position and force are divided by their Huber widths: unit gradients)
W_INSIDE = 0.3
W_FORCE = 1.0


def fsr_loss(raw: torch.Tensor, targets: dict[str, torch.Tensor]) -> torch.Tensor:
    """BCE for contact and inside, Huber for position (mm) and log force, on contact frames.

    ``raw`` is :meth:`FsrNet.raw`; ``targets`` (from ``FsrTask.training_batch``): ``xy_mm`` (B, 2),
    ``log_force`` (B,), ``contact`` (B,: a contact the film can feel), ``position_weight`` (B,: 1 on
    every contact frame), ``inside`` (B,), all float32.
    """
    weight = targets["position_weight"]
    bce = nn.functional.binary_cross_entropy_with_logits
    huber = nn.functional.huber_loss
    n_contact = weight.sum().clamp_min(1.0)  # >= 1: no division by zero on a batch without contact
    contact = weight
    loss_contact = bce(raw[:, 3], targets["contact"])
    loss_inside = (bce(raw[:, 4], targets["inside"], reduction="none") * contact).sum() / n_contact
    xy_err = huber(raw[:, 0:2], targets["xy_mm"], reduction="none", delta=XY_DELTA_MM).sum(dim=1)
    loss_xy = (xy_err * contact).sum() / n_contact / XY_DELTA_MM
    f_err = huber(raw[:, 2], targets["log_force"], reduction="none", delta=LOGF_DELTA)
    loss_f = (f_err * contact).sum() / n_contact / LOGF_DELTA
    return loss_contact + W_INSIDE * loss_inside + loss_xy + W_FORCE * loss_f
