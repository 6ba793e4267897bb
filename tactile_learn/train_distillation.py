"""Knowledge distillation for ``train``: a teacher network's maps as targets on some of the folders.

A general model trained on a mixture of datasets may learn one of them (the two-sphere set) less
well than a specialist trained on it alone. With ``--teacher``, the frames of the folders named in
``--teacher-data`` are supervised with the specialist's output (blended with the truth at
``--teacher-weight``) while every other frame keeps its ground truth: the specialist's map is the
answer under that folder's prior, a lower-variance target than one sampled truth (two identical
spheres on distinct rows and columns: the truth picks one diagonal at random, the specialist
resolves it as well as the readings allow).

The teacher sees exactly the student's (mirrored) readings, so augmentation needs no care; it runs
in inference mode, so it adds its forward pass, not a backward one, to a taught batch.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from synth.errors import ConfigError
from synth.scene import Scene
from tactile_learn.torch_estimator import TorchEstimator

__all__ = ["PART_KEY", "Teacher"]

#: the key under which :meth:`tactile_learn.training_sets.TrainingSet.iter_batches` reports each
#: frame's folder (its index in the training set's folders)
PART_KEY = "_part"


class Teacher:
    """The network in ``source`` (a run folder or a model's ``NAME.pt``) teaching the frames of the
    folders ``taught`` (indices into the training set's folders): their target becomes
    ``weight * teacher + (1 - weight) * truth``."""

    def __init__(self, source: str, scene: Scene, taught: Sequence[int], weight: float, device: str = "cpu") -> None:
        if not (0.0 < weight <= 1.0):
            raise ConfigError(f"--teacher-weight: {weight} is out of range (0, 1]")
        if not taught:
            raise ConfigError("--teacher: name the folders it teaches with --teacher-data")
        self.estimator = TorchEstimator.from_checkpoint(source, scene)
        self.net = self.estimator.net
        self.net.eval()
        self.device = device  # the student's: the teacher reads the same batch where it lies
        self.net.to(device)
        self.taught = np.asarray(sorted(set(taught)), dtype=np.int64)
        self.weight = float(weight)
        self.source = source

    @torch.inference_mode()
    def maps(self, inputs: np.ndarray) -> np.ndarray:
        """The teacher's output for a batch of (already augmented) inputs, float32."""
        x = torch.from_numpy(np.ascontiguousarray(inputs, dtype=np.float32))
        out = self.net(x if self.device == "cpu" else x.to(self.device))
        if isinstance(out, tuple):  # a network with intermediate maps: the final one
            out = out[0]
        return out.cpu().numpy()

    def targets(self, inputs: np.ndarray, target: np.ndarray, part: np.ndarray) -> np.ndarray:
        """``target`` with the taught frames' rows replaced by the blend (a new array; the others as given)."""
        mask = np.isin(part, self.taught)
        if not mask.any():
            return target
        taught = self.maps(inputs[mask])
        if taught.shape != target[mask].shape:
            raise ConfigError(
                f"--teacher: {self.source} outputs {taught.shape[1:]}, the training targets are {target.shape[1:]}"
            )
        out = target.copy()
        out[mask] = self.weight * taught + (1.0 - self.weight) * target[mask]
        return out
