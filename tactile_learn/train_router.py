"""Fitting the small readings MLP behind the routers (torch: training only).

One network for every router of strip frames: :mod:`tactile_learn.prior_route`'s routed cards and
:mod:`tactile_learn.known_objects`' bundles run it in numpy from the arrays :func:`router_arrays` gives;
the research scripts (``scripts/strips_experts.py`` and those built on it) fit their routers and flags
with it too.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["fit_mlp", "router_arrays"]


def fit_mlp(
    xt: Any,
    target: Any,
    fit: np.ndarray,
    rng: np.random.Generator,
    seed: int,
    outputs: int,
    loss_of: Callable[[Any, Any], Any],
    on_epoch: Callable[[int, Any, Any], None] | None = None,
) -> Any:
    """A small MLP (inputs -> 96 -> 96 -> ``outputs``) fitted to ``target`` on the rows ``fit`` of the
    normalised features ``xt`` (a float32 tensor): 60 epochs of batches of 256 drawn with ``rng``, AdamW,
    one cycle to 2e-3; ``on_epoch(epoch, net, last_loss)`` after each epoch. Returns the net in eval mode."""
    import torch

    torch.manual_seed(seed)
    net = torch.nn.Sequential(
        torch.nn.Linear(xt.shape[1], 96), torch.nn.ReLU(), torch.nn.Linear(96, 96), torch.nn.ReLU(),
        torch.nn.Linear(96, outputs),
    )  # fmt: skip
    opt = torch.optim.AdamW(net.parameters(), lr=2e-3, weight_decay=1e-4)
    epochs = 60
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=2e-3, total_steps=epochs * (len(fit) // 256 + 1))
    for epoch in range(epochs):
        net.train()
        perm = torch.from_numpy(rng.permutation(fit))
        for i in range(0, len(perm), 256):
            idx = perm[i : i + 256]
            loss = loss_of(net(xt[idx]), target[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
        if on_epoch is not None:
            on_epoch(epoch, net, loss)
    net.eval()
    return net


def router_arrays(net: Any, mean: np.ndarray, std: np.ndarray) -> dict[str, np.ndarray]:
    """The arrays of a router file (:data:`tactile_learn.prior_route._ARRAYS`) from a :func:`fit_mlp` net
    and the features' mean and scale it was fitted on."""
    layers = [net[0], net[2], net[4]]
    arrays = {"mean": np.asarray(mean), "std": np.asarray(std)}
    for k, layer in enumerate(layers):
        arrays[f"w{k}"] = layer.weight.detach().numpy()
        arrays[f"b{k}"] = layer.bias.detach().numpy()
    return {k: np.asarray(v, dtype=np.float32) for k, v in arrays.items()}
