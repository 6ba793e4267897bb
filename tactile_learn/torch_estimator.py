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

    def __init__(
        self,
        net: torch.nn.Module,
        task: str,
        scene: Scene,
        name: str = "torch",
        batch_size: int = 4096,
        backend: str = "torch",
        checkpoint: dict[str, Any] | None = None,
    ) -> None:
        self.net = net
        self.task_name = task
        self.scene = scene
        self.name = name
        self.batch_size = batch_size
        self.backend = backend
        #: what the weights file held besides the network (task, size, stats, a run's result)
        self.checkpoint = checkpoint or {}

    @property
    def is_classifier(self) -> bool:  # type: ignore[override]
        """Whether the task classifies (thermal): ``predict_proba`` and labels from ``predict``."""
        return self.task_name == "thermal"

    def prepare(self) -> TorchEstimator:
        """Look the task up once (its input check and the completion of a raw prediction)."""
        if "task_" not in self.__dict__:
            self.task_ = get_task(self.task_name)
            self.input_check_ = self.task_.input_check(self.scene)
            self.finish_ = self.task_.prediction_finisher(self.scene)
        return self

    @classmethod
    def from_checkpoint(
        cls,
        source: str | Path,
        scene: Scene | None = None,
        name: str | None = None,
        threads: int | None = None,
        backend: str = "torch",
    ) -> TorchEstimator:
        """The network of a finished run folder or a model's ``NAME.pt`` (see
        :mod:`tactile_learn.checkpoints`), on ``scene`` (default: the one it was trained on),
        prepared; ``threads`` sets torch's intra-op threads (process-wide). The one way from weights
        on disk to a network: export, fine-tuning (``train --init``) and bench's torch backend all
        load through it."""
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
        return cls(
            build_net(saved, scene), str(saved["task"]), scene, name=label, checkpoint=saved, backend=backend
        ).prepare()

    def predict(self, X: np.ndarray) -> np.ndarray:
        """The network's output (a classifier's: the most probable label, int64)."""
        out = self.predict_proba(X)
        return out.argmax(axis=1).astype(np.int64) if self.is_classifier else out

    @torch.inference_mode()
    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """The network's output for ``X`` (a classifier's: probabilities)."""
        self.prepared_state("task_")  # an unprepared estimator fails before any work
        x = self.input_check_(X)
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
        return self.finish_(x, raw)
