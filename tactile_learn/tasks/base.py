"""What a task (strips, thermal, fsr) tells the generic machinery: eval, train, export, bench.

A task names its estimator input and truth arrays, lists its classical methods, loads evaluation
data (a generated dataset, an ``.npz`` file or the task's own recording format), computes its
metrics, and, for learning, builds its torch networks and loss. Everything generic (the training
loop, checkpoints, ONNX export, the runtime, the benchmark, the CLI) lives elsewhere and asks the
task. Torch is only imported inside the learning methods.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from synth.dataset import Dataset, load_arrays
from synth.errors import DataError, InputError
from synth.scene import Scene, load_scene
from tactile_learn.estimators.base import Estimator
from tactile_learn.validation.common import as_batch

if TYPE_CHECKING:  # torch only for type checking: importing a task never imports torch
    import torch

__all__ = ["EvalData", "Task", "readable_frames"]


@dataclass
class EvalData:
    """Frames to evaluate on.

    ``inputs`` is what ``Estimator.predict`` takes (batch first, float32); ``truth`` holds the
    arrays the metrics compare against; ``extra`` holds anything else known per frame (latent
    parameters, group labels) for breakdowns.
    """

    inputs: np.ndarray
    truth: dict[str, np.ndarray]
    scene: Scene
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = ""

    def __len__(self) -> int:
        return len(self.inputs)

    def subset(self, index: np.ndarray | slice) -> EvalData:
        """The frames selected by ``index`` (arrays of per-frame data are indexed alike)."""
        return EvalData(
            inputs=self.inputs[index],
            truth={k: v[index] for k, v in self.truth.items()},
            scene=self.scene,
            extra={k: v[index] for k, v in self.extra.items()},
            source=self.source,
        )


class Task(ABC):
    #: task name, also the scene table and the CLI's ``--task`` value
    name: ClassVar[str]
    #: scene used when the user names none
    default_scene: ClassVar[str]
    #: dataset array that estimators take as input, and the ONNX input name
    input_key: ClassVar[str]
    #: ONNX output name (the array ``predict`` returns)
    output_key: ClassVar[str]
    #: dataset arrays that training and metrics need besides the input
    truth_keys: ClassVar[tuple[str, ...]]
    #: (metric name, True if higher is better): early stopping, bench Pareto plots
    primary_metric: ClassVar[tuple[str, bool]]
    #: network sizes ``build_net`` accepts, smallest first
    net_sizes: ClassVar[tuple[str, ...]] = ()
    #: training epochs when the user names none (the default run must reach the task's floors)
    default_epochs: ClassVar[int] = 30
    #: training samples read to compute the normalisation statistics
    stats_limit: ClassVar[int] = 20000
    #: held-out samples the benchmark simulates by default (its --quick run takes a quarter)
    bench_samples: ClassVar[int] = 2000

    @property
    def train_keys(self) -> tuple[str, ...]:
        """Dataset arrays that ``training_batch`` needs (default: the input and the truth)."""
        return (self.input_key, *self.truth_keys)

    def train_keys_for(self, scene: Scene) -> tuple[str, ...]:
        """The arrays ``training_batch`` needs for ``scene`` (default: :attr:`train_keys`)."""
        return self.train_keys

    # ---- data and evaluation (numpy only) ----------------------------------------------------

    def read_arrays(self, source: str | Path, scene: Scene | None) -> tuple[dict[str, np.ndarray], Scene]:
        """Arrays and scene of a generated dataset folder (its own scene unless one is given) or an
        ``.npz`` file (the given scene, else the task's default)."""
        path = Path(source)
        if path.is_dir():
            dataset = Dataset(path)
            if dataset.scene.task != self.name:
                raise DataError(f"{path}: dataset is for task {dataset.scene.task!r}, not {self.name!r}")
            return dataset.arrays(), scene or dataset.scene
        return load_arrays(path), scene or load_scene(self.default_scene)

    @abstractmethod
    def input_shape(self, scene: Scene) -> tuple[int, ...]:
        """Per-frame shape of ``predict``'s input for ``scene``."""

    def input_layout(self, scene: Scene) -> dict[str, Any]:
        """What each input entry is, for the model card's ``inputs`` (empty: see the task's docs)."""
        return {}

    def output_labels(self, scene: Scene) -> tuple[str, ...]:
        """Names of ``predict``'s output classes for ``scene`` (empty for regression tasks): a model
        applied to another scene of the same sensor must predict the same classes in the same order."""
        return ()

    @abstractmethod
    def classical_methods(self) -> dict[str, Callable[[Scene], Estimator]]:
        """Registry of classical estimators: name -> factory taking the scene."""

    @abstractmethod
    def load_eval_data(self, source: str | Path, scene: Scene | None = None) -> EvalData:
        """Frames from a dataset folder, an ``.npz`` file, or the task's recording format."""

    @abstractmethod
    def metrics(self, pred: np.ndarray, data: EvalData) -> dict[str, Any]:
        """Metrics of predictions ``pred`` (what ``predict`` returned for ``data.inputs``)."""

    def example_inputs(self, arrays: dict[str, np.ndarray], scene: Scene) -> np.ndarray:
        """Estimator inputs from simulated dataset arrays (default: the ``input_key`` array). A task
        whose dataset stores whole recordings (thermal: a touch of 16 pixels) cuts them here."""
        return np.asarray(arrays[self.input_key], dtype=np.float32)

    def latency_inputs(self, data: EvalData) -> np.ndarray:
        """Single frames the benchmark times ``predict`` on (default: ``data.inputs``)."""
        return data.inputs

    def reference_metrics(self, data: EvalData, limit: int | None = None) -> dict[str, Any]:
        """Method-independent metrics of ``data`` (thermal: the oracle's accuracy); default none."""
        return {}

    def card_extras(self, model: Estimator, val: str | None, scene: Scene) -> dict[str, Any]:
        """Entries an exported model's card adds besides the generic ones, measured with the exported
        ``model`` on the run's validation data ``val`` (default: none)."""
        return {}

    def finish_prediction(self, inputs: np.ndarray, prediction: np.ndarray, scene: Scene) -> np.ndarray:
        """Complete a method's raw prediction for validated ``inputs`` (every estimator, classical
        or learned, returns this): default unchanged. The fsr task appends its one-press check."""
        return prediction

    def prediction_finisher(self, scene: Scene) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
        """:meth:`finish_prediction` for ``scene`` with its set-up done once (an estimator builds it
        in ``prepare``): ``finisher(inputs, prediction)``."""
        return partial(_finish, self, scene)

    def same_sensor(self, a: Scene, b: Scene) -> bool:
        """Whether a model trained on scene ``a`` applies to scene ``b`` as it is (default: the same
        scene digest; a task whose scenes also describe stimuli compares the sensor alone)."""
        return a.digest == b.digest

    def check_inputs(self, inputs: Any, scene: Scene) -> np.ndarray:
        """Validated float32 batch for ``predict``: :meth:`input_check` applied once."""
        return self.input_check(scene)(inputs)

    def input_check(self, scene: Scene) -> Callable[[Any], np.ndarray]:
        """The scene's input check with its limits worked out once (an estimator builds it in
        ``prepare`` and calls it on every batch). Tasks override it with their sensor's check in
        :mod:`tactile_learn.validation` (its physical bounds, e.g. a saturated ADC)."""
        return partial(as_batch, feature_shape=self.input_shape(scene), name=self.input_key)

    def fast_bounds(self, scene: Scene) -> tuple[float, float, bool] | None:
        """``(low, high, low_strict)``: a float32 batch of the right shape whose values all satisfy
        ``low <= x < high`` (``low < x`` where ``low_strict``) passes :meth:`check_inputs` unchanged,
        so the streaming fast path may check it with two reductions (NaN fails both comparisons).
        ``None`` (the default) where ``check_inputs`` does more than check (e.g. maps a calibrated
        film's readings): the fast path then calls it."""
        return None

    def empty_prediction(self, n: int, scene: Scene) -> np.ndarray:
        """What every method answers for ``n`` frames with nothing touching the sensor (the idle
        gate of :mod:`tactile_learn.frame_stream` returns it without running the estimator)."""
        raise NotImplementedError(f"task {self.name!r} has no empty prediction")

    def calibrate(self, source: str | Path, out: str | Path, scene: Scene) -> dict[str, Any]:
        """Fit the user's own sensor from labelled recordings in ``source``; write a scene TOML
        (usable by ``generate --scene``) to ``out``; return a summary for the CLI to print."""
        raise NotImplementedError(f"task {self.name!r} has no calibration")

    def evaluate(self, estimator: Estimator, data: EvalData) -> dict[str, Any]:
        """Metrics of ``estimator`` (prepared here if it is not yet) on ``data``. Tasks that evaluate
        several views of the same frames (e.g. thermal contact durations) override this."""
        return self.metrics(estimator.prepare().predict(data.inputs), data)

    # ---- learning (torch imported inside the implementations) --------------------------------

    def fit_stats(self, arrays: dict[str, np.ndarray], scene: Scene) -> dict[str, Any]:
        """Normalisation statistics from (a sample of) the training arrays; JSON-serialisable."""
        raise NotImplementedError(f"task {self.name!r} has no learned models")

    def training_batch(
        self, arrays: dict[str, np.ndarray], scene: Scene, rng: np.random.Generator
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Network input and loss targets for one batch of dataset arrays (augmentation goes here)."""
        raise NotImplementedError(f"task {self.name!r} has no learned models")

    def build_net(self, size: str, scene: Scene, stats: dict[str, Any]) -> torch.nn.Module:
        """A network mapping raw float32 inputs to exactly what ``predict`` returns (normalisation
        inside, as buffers, so the exported ONNX graph is self-contained)."""
        raise NotImplementedError(f"task {self.name!r} has no learned models")

    def train_forward(self, net: torch.nn.Module, inputs: torch.Tensor) -> torch.Tensor:
        """The output the loss sees during training (default ``net(inputs)``); a classifier may
        return logits here while its ``forward`` returns probabilities."""
        output: torch.Tensor = net(inputs)
        return output

    def export_module(self, net: torch.nn.Module, scene: Scene) -> tuple[torch.nn.Module, list[str]]:
        """The module exported to ONNX and its output names, the first being :attr:`output_key`
        (what ``predict`` returns); a task may add outputs (strips: the readings residual)."""
        return net, [self.output_key]

    def loss(self, output: torch.Tensor, targets: dict[str, torch.Tensor]) -> torch.Tensor:
        """Training loss of the network output against the targets from ``training_batch``."""
        raise NotImplementedError(f"task {self.name!r} has no learned models")


def _finish(task: Task, scene: Scene, inputs: np.ndarray, prediction: np.ndarray) -> np.ndarray:
    return task.finish_prediction(inputs, prediction, scene)


def readable_frames(task: Task, data: EvalData) -> tuple[EvalData, dict[str, Any]]:
    """The frames of ``data`` that the task's input check accepts, and what was left out
    (``share``, ``first_reason``). A sensor whose ADC saturates under strong presses (few bits, a thin
    cover) makes frames no estimator may read (their loads are unknown): they are a property of the
    design, to be counted, not a reason to stop an evaluation. Nothing readable is a DataError."""
    keep = np.ones(len(data), bool)
    reason = ""
    for i in range(len(data)):
        try:
            task.check_inputs(data.inputs[i : i + 1], data.scene)
        except InputError as exc:
            keep[i] = False
            reason = reason or str(exc)
    if len(data) and not keep.any():
        raise DataError(f"{data.source or 'data'}: no frame can be read by this sensor ({reason})")
    share = float(1 - keep.mean()) if len(data) else 0.0
    return data.subset(np.flatnonzero(keep)), {"share": share, "first_reason": reason}
