"""Training of the rule-correction specialist (:mod:`tactile_learn.nets.strips_rule_correction`) on
one family's frames: the loss is 1 - the per-frame Pearson r (the suites' figure), one-cycle AdamW,
the epoch with the best validation r kept. Small and single-threaded by design: it answers "how far
above the rule can this family go", it is not a shipped model's recipe."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from synth.errors import ConfigError
from synth.scene import Scene
from synth.sensors.strips import StripSensor
from tactile_learn.nets.strips_rule_correction import RuleCorrectionNet, pearson_loss

__all__ = ["RuleCorrectionConfig", "strip_loads_f32", "train_rule_correction"]


@dataclass(frozen=True)
class RuleCorrectionConfig:
    hidden: int = 512
    depth: int = 3
    epochs: int = 8
    batch: int = 512
    lr: float = 1e-3
    weight_decay: float = 1e-4
    seed: int = 0


def strip_loads_f32(scene: Scene, readings: np.ndarray) -> torch.Tensor:
    """The specialist's input: every strip's load (``StripSensor.invert_readings``), float32."""
    sensor = StripSensor(scene.sensor)
    return torch.from_numpy(sensor.invert_readings(np.asarray(readings, dtype=np.float64)).astype(np.float32))


def _mean_r(net: RuleCorrectionNet, loads: torch.Tensor, truth: torch.Tensor) -> float:
    with torch.inference_mode():
        losses = [pearson_loss(net(loads[i : i + 4096]), truth[i : i + 4096]) for i in range(0, len(loads), 4096)]
        sizes = [len(loads[i : i + 4096]) for i in range(0, len(loads), 4096)]
    return 1.0 - float(np.average([float(v) for v in losses], weights=sizes))


def train_rule_correction(
    scene: Scene,
    train: tuple[np.ndarray, np.ndarray],
    val: tuple[np.ndarray, np.ndarray],
    config: RuleCorrectionConfig = RuleCorrectionConfig(),
    progress: Callable[[str], None] | None = None,
) -> tuple[RuleCorrectionNet, list[float]]:
    """Train on ``train`` = (readings (B, C), pressure maps (B, N, M)); returns the net at its best
    validation epoch and the validation r after each epoch (the rule's own before the first)."""
    if config.epochs < 1 or config.batch < 1 or not config.lr > 0:
        raise ConfigError(f"rule correction: epochs, batch and lr must be positive, got {config}")
    if len(train[0]) != len(train[1]) or len(val[0]) != len(val[1]):
        raise ConfigError("rule correction: readings and maps differ in number of frames")
    if len(train[0]) < config.batch:
        raise ConfigError(f"rule correction: {len(train[0])} training frames, fewer than one batch ({config.batch})")
    torch.manual_seed(config.seed)
    x_tr, y_tr = strip_loads_f32(scene, train[0]), torch.as_tensor(train[1], dtype=torch.float32)
    x_va, y_va = strip_loads_f32(scene, val[0]), torch.as_tensor(val[1], dtype=torch.float32)
    net = RuleCorrectionNet(scene, hidden=config.hidden, depth=config.depth)
    steps = config.epochs * (len(x_tr) // config.batch)
    opt = torch.optim.AdamW(net.parameters(), config.lr, weight_decay=config.weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, config.lr, total_steps=steps, pct_start=0.05)
    history = [_mean_r(net, x_va, y_va)]
    best = (history[0], {k: v.clone() for k, v in net.state_dict().items()})
    generator = torch.Generator().manual_seed(config.seed)
    for epoch in range(config.epochs):
        order = torch.randperm(len(x_tr), generator=generator)
        net.train()
        for start in range(0, len(x_tr) - config.batch + 1, config.batch):
            pick = order[start : start + config.batch]
            loss = pearson_loss(net(x_tr[pick]), y_tr[pick])
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
        net.eval()
        history.append(_mean_r(net, x_va, y_va))
        if history[-1] > best[0]:
            best = (history[-1], {k: v.clone() for k, v in net.state_dict().items()})
        if progress:
            progress(f"epoch {epoch + 1}/{config.epochs}: validation r {history[-1]:.4f} (rule {history[0]:.4f})")
    net.load_state_dict(best[1])
    return net, history
