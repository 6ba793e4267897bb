"""Per-family evaluation on a suite (``synth.suite``): the same metrics as ``eval``, per family of
shapes, and their mean over families (each family weighs the same, whatever its frame count)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from synth.errors import ConfigError
from synth.suite import Suite, suite_frames
from tactile_learn.estimators.base import Estimator
from tactile_learn.tasks import get_task
from tactile_learn.tasks.base import EvalData

__all__ = ["SUITE_SEED", "evaluate_suite", "mean_over_families", "suite_eval_data"]

#: frames of a suite drawn when no seed is given: no training or validation set uses it
SUITE_SEED = 4_242_424


def suite_eval_data(suite: Suite, n: int | None = None, seed: int = SUITE_SEED) -> dict[str, EvalData]:
    """Every family's frames as evaluation data (``n`` per family, default the suite's)."""
    task = get_task(suite.base.task)
    data: dict[str, EvalData] = {}
    for family, arrays in zip(suite.families, suite_frames(suite, n, seed).values(), strict=True):
        scene = family.scene
        inputs = task.example_inputs(arrays, scene)
        truth = {k: arrays[k] for k in task.truth_keys}
        extra = {k: v for k, v in arrays.items() if k.startswith("latent_")}
        data[family.name] = EvalData(
            inputs=inputs, truth=truth, scene=scene, extra=extra, source=f"{suite.name}/{family.name} seed {seed}"
        )
    return data


def mean_over_families(families: dict[str, dict[str, Any]]) -> dict[str, float]:
    """Mean of every scalar metric over the families that have it."""
    keys = sorted({k for m in families.values() for k, v in m.items() if isinstance(v, (int, float))})
    means = {}
    for key in keys:
        values = [float(m[key]) for m in families.values() if isinstance(m.get(key), (int, float))]
        values = [v for v in values if np.isfinite(v)]
        if values:
            means[key] = float(np.mean(values))
    return means


def evaluate_suite(
    estimator: Estimator,
    data: dict[str, EvalData],
    task_name: str,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """``{"families": {name: metrics}, "mean_over_families": {...}, "seconds"}`` of one estimator."""
    task = get_task(task_name)
    if not data:
        raise ConfigError("the suite has no families to evaluate")
    families: dict[str, dict[str, Any]] = {}
    start = time.perf_counter()
    for name, frames in data.items():
        if progress:
            progress(name)
        families[name] = {"n_frames": len(frames), **task.evaluate(estimator, frames)}
    return {
        "families": families,
        "mean_over_families": mean_over_families(families),
        "seconds": time.perf_counter() - start,
    }
