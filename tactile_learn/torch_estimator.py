"""A torch network behind the estimator interface (training-time validation, bench's torch-eager
backend). Imports torch: never imported by the runtime or the classical path."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch

from synth.errors import ModelError
from synth.scene import Scene
from tactile_learn.estimators.base import Estimator
from tactile_learn.tasks import get_task

__all__ = ["TorchEstimator"]


class TorchEstimator(Estimator):
    kind = "learned"
    backend = "torch"

    def __init__(
        self,
        net: torch.nn.Module,
        task: str,
        scene: Scene,
        name: str = "torch",
        batch_size: int = 4096,
        checkpoint: dict[str, Any] | None = None,
    ) -> None:
        self.net = net
        self.task_name = task
        self.scene = scene
        self.name = name
        self.batch_size = batch_size
        #: what the weights file held besides the network (task, size, stats, a run's result)
        self.checkpoint = checkpoint or {}

    @classmethod
    def from_checkpoint(
        cls, source: str | Path, scene: Scene | None = None, name: str | None = None, threads: int | None = None
    ) -> TorchEstimator:
        """The network of a finished run folder or a model's ``NAME.pt`` (see
        :mod:`tactile_learn.checkpoints`), on ``scene`` (default: the one it was trained on);
        ``threads`` sets torch's intra-op threads (process-wide). The one way from weights on disk to a
        network: export, fine-tuning (``train --init``) and bench's torch backend all load through it."""
        from tactile_learn.checkpoints import build_net, load_weights, weights_scene

        saved = load_weights(source)
        if scene is not None and scene.task != saved["task"]:
            raise ModelError(
                f"{source}: the weights are for task {saved['task']!r}, scene {scene.name!r} is {scene.task!r}"
            )
        scene = scene or weights_scene(saved)
        if threads:
            torch.set_num_threads(threads)
        label = name or Path(source).name  # NAME.pt, or the run folder's name
        return cls(build_net(saved, scene), str(saved["task"]), scene, name=label, checkpoint=saved)

    def fit(self, X: np.ndarray, y: Any = None) -> TorchEstimator:
        return self

    @torch.inference_mode()
    def predict(self, X: np.ndarray) -> np.ndarray:
        x = get_task(self.task_name).check_inputs(X, self.scene)
        was_training = self.net.training
        self.net.eval()
        try:
            if len(x) == 0:  # ask the network for its output shape with one dummy frame
                probe = self.net(torch.zeros((1, *x.shape[1:]))).numpy()
                raw = np.zeros((0, *probe.shape[1:]), dtype=np.float32)
            else:
                parts = [
                    self.net(torch.from_numpy(x[i : i + self.batch_size])).numpy()
                    for i in range(0, len(x), self.batch_size)
                ]
                raw = np.concatenate(parts).astype(np.float32, copy=False)
        finally:
            self.net.train(was_training)
        return get_task(self.task_name).finish_prediction(x, raw, self.scene)
