"""Every registered estimator of every task obeys the one interface (scikit-learn conventions)."""

from __future__ import annotations

import inspect
from functools import cache

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.errors import InputError
from synth.scene import Scene, load_scene
from tactile_learn.estimators.base import Estimator
from tactile_learn.tasks import TASK_NAMES, get_task

CASES = [(task, method) for task in TASK_NAMES for method in get_task(task).classical_methods()]


@cache
def sample(task: str) -> tuple[Scene, np.ndarray]:
    t = get_task(task)
    scene = load_scene(t.default_scene)
    arrays = simulate_shard(scene, 777, 0, 12)
    return scene, np.asarray(t.example_inputs(arrays, scene), dtype=np.float32)[:24]


def make(task: str, method: str) -> tuple[Estimator, np.ndarray]:
    scene, x = sample(task)
    return get_task(task).classical_methods()[method](scene), x


@pytest.mark.parametrize(("task", "method"), CASES)
def test_interface(task: str, method: str) -> None:
    est, x = make(task, method)
    assert isinstance(est, Estimator) and est.task == task and est.kind == "classical"
    params = est.get_params()
    init = [p for p in inspect.signature(type(est).__init__).parameters if p != "self"]
    assert list(params) == init  # __init__ stores its parameters under their own names
    assert est.fit(x) is est
    pred = est.predict(x)
    assert pred.dtype == (np.int64 if est.is_classifier else np.float32)  # a classifier's labels
    assert len(pred) == len(x) and np.isfinite(pred).all()
    assert np.array_equal(pred, est.predict(x))  # deterministic
    again = type(est)(**params).prepare().predict(x)
    assert np.array_equal(pred, again)


@pytest.mark.parametrize(("task", "method"), CASES)
def test_batch_sizes_layouts_and_read_only_input(task: str, method: str) -> None:
    est, x = make(task, method)
    full = est.predict(x)
    assert est.predict(x[:0]).shape == (0, *full.shape[1:])
    single = est.predict(x[3:4])
    assert np.allclose(single[0], full[3], rtol=1e-4, atol=1e-5)
    frozen = x.copy()
    frozen.setflags(write=False)
    assert np.allclose(est.predict(frozen), full, rtol=1e-5, atol=1e-6)
    doubled = np.repeat(x, 2, axis=0)[::2]  # non-contiguous view
    assert not doubled.flags.c_contiguous or doubled.base is not None
    assert np.allclose(est.predict(doubled), full, rtol=1e-5, atol=1e-6)
    assert np.allclose(est.predict(x.astype(np.float64)), full, rtol=1e-5, atol=1e-6)
    untouched = x.copy()
    est.predict(x)
    assert np.array_equal(x, untouched)


@pytest.mark.parametrize(("task", "method"), CASES)
def test_bad_input_gets_a_clear_error(task: str, method: str) -> None:
    est, x = make(task, method)
    bad = x.copy()
    bad[1].flat[0] = np.nan
    with pytest.raises(InputError, match="NaN"):
        est.predict(bad)
    bad[1].flat[0] = np.inf
    with pytest.raises(InputError, match="NaN or inf"):
        est.predict(bad)
    with pytest.raises(InputError, match="expected shape"):
        est.predict(x[:, ..., :-1] if x.ndim == 2 else x[..., :-1])
    with pytest.raises(InputError, match="expected shape"):
        est.predict(x[0])
    with pytest.raises(InputError, match="expected numbers"):
        est.predict(np.array([["a"] * x.shape[-1]]))
    negative = x.copy()
    negative[0].flat[0] = -1.0
    with pytest.raises(InputError, match="negative"):
        est.predict(negative)
