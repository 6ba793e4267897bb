"""scikit-learn's rules over every registered estimator: state is built in ``prepare``/``fit``,
``predict`` changes nothing (as scikit-learn's ``check_dict_unchanged``: a deep comparison of
``vars(est)`` before and after), classifiers give labels from ``predict`` and probabilities from
``predict_proba``, and ``backend`` is a constructor parameter.

Registered: every classical method of every task (``Task.classical_methods``), every shipped ONNX
model on its card's scene, the checked strip model, and a shipped model's torch network (skipped
without torch)."""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.scene import Scene, load_scene
from tactile_learn.estimators.base import Estimator, NotPreparedError
from tactile_learn.methods import shipped_models
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.tasks import TASK_NAMES, get_task

ROOT = Path(__file__).resolve().parents[3]


def _shipped() -> list[tuple[str, Path]]:
    return [(task, path) for task in TASK_NAMES for path in sorted(shipped_models(task).values())]


def _factories() -> dict[str, Callable[[], Estimator]]:
    out: dict[str, Callable[[], Estimator]] = {}
    for task in TASK_NAMES:
        for name, factory in get_task(task).classical_methods().items():
            out[f"{task}:{name}"] = lambda f=factory, t=task: f(load_scene(get_task(t).default_scene))
    for _, path in _shipped():
        out[f"onnx:{path.stem}"] = lambda p=path: OnnxEstimator(p).prepare()
    strips16 = ROOT / "models" / "strips16.onnx"
    if strips16.is_file():
        from tactile_learn.strips_guard import CheckedStripModel

        out["checked:strips16"] = lambda: CheckedStripModel(strips16).prepare()
    return out


FACTORIES = _factories()
NAMES = sorted(FACTORIES)


@cache
def _estimator(name: str) -> Estimator:
    return FACTORIES[name]()


def _scene(est: Estimator) -> Scene:
    scene = getattr(est, "scene_", None) or est.scene  # type: ignore[attr-defined]
    assert isinstance(scene, Scene)
    return scene


@cache
def _inputs(scene_digest: str, scene: Scene) -> np.ndarray:
    task = get_task(scene.task)
    arrays = simulate_shard(scene, 4242, 0, 2 if scene.task == "thermal" else 8)
    return np.ascontiguousarray(task.example_inputs(arrays, scene)[:6], dtype=np.float32)


def inputs_of(est: Estimator) -> np.ndarray:
    scene = _scene(est)
    return _inputs(scene.digest, scene)


def fingerprint(value: Any, depth: int = 0, seen: set[int] | None = None) -> Any:
    """A comparable deep snapshot of ``value``: arrays by dtype, shape and content hash, containers
    and objects (their ``__dict__``, dataclass fields) recursively, so a cache filled inside a
    nested object counts; opaque objects (sessions, functions) by identity."""
    seen = set() if seen is None else seen
    if value is None or isinstance(value, bool | int | float | complex | str | bytes):
        return value
    if hasattr(value, "detach") and hasattr(value, "cpu"):  # a torch tensor
        value = value.detach().cpu().numpy()
    if isinstance(value, np.ndarray | np.generic):
        array = np.ascontiguousarray(value)
        return ("array", array.dtype.str, array.shape, hashlib.sha256(array.tobytes()).hexdigest())
    if id(value) in seen or depth > 12:  # a cycle, or deeper than any estimator's own state
        return ("ref", type(value).__name__)
    seen = seen | {id(value)}
    if isinstance(value, dict):
        return {repr(k): fingerprint(v, depth + 1, seen) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return (type(value).__name__, [fingerprint(v, depth + 1, seen) for v in value])
    if isinstance(value, set | frozenset):
        return ("set", sorted(repr(v) for v in value))
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {f.name: getattr(value, f.name) for f in dataclasses.fields(value)}
        return (type(value).__name__, fingerprint({**fields, **getattr(value, "__dict__", {})}, depth + 1, seen))
    if hasattr(value, "__dict__") and not callable(value) and not isinstance(value, type):
        return (type(value).__name__, fingerprint(vars(value), depth + 1, seen))
    if hasattr(value, "state_dict") and hasattr(value, "training"):  # a torch module
        return ("module", value.training, fingerprint(dict(value.state_dict()), depth + 1, seen))
    return ("opaque", type(value).__name__, id(value))


def test_every_task_and_shipped_model_is_covered() -> None:
    assert {name.split(":")[0] for name in NAMES} >= {*TASK_NAMES, "onnx"}
    assert all(f"onnx:{path.stem}" in FACTORIES for _, path in _shipped())


@pytest.mark.parametrize("name", NAMES)
def test_predict_changes_nothing(name: str) -> None:
    est = _estimator(name)
    x = inputs_of(est)
    before = fingerprint(vars(est))
    first = est.predict(x)
    assert fingerprint(vars(est)) == before
    if est.is_classifier:
        est.predict_proba(x)  # type: ignore[attr-defined]
        assert fingerprint(vars(est)) == before
    est.predict_checked(get_task(_scene(est).task).check_inputs(x, _scene(est)))
    assert fingerprint(vars(est)) == before
    assert np.array_equal(est.predict(x), first)


@pytest.mark.parametrize("name", NAMES)
def test_prepare_builds_everything_once(name: str) -> None:
    est = _estimator(name)
    before = fingerprint(vars(est))
    assert est.prepare() is est
    assert fingerprint(vars(est)) == before  # idempotent: nothing rebuilt


@pytest.mark.parametrize("name", [n for n in NAMES if not n.startswith("checked:")])
def test_unprepared_predict_names_the_fix_and_changes_nothing(name: str) -> None:
    est = _estimator(name)
    fresh = type(est)(**est.get_params())
    before = fingerprint(vars(fresh))
    with pytest.raises(NotPreparedError, match=r"prepare\(\)"):
        fresh.predict(inputs_of(est))
    assert fingerprint(vars(fresh)) == before
    assert fresh.fit() is fresh  # fit prepares (no method here needs data to)
    assert np.array_equal(fresh.predict(inputs_of(est)), est.predict(inputs_of(est)))


@pytest.mark.parametrize("name", NAMES)
def test_classifiers_give_labels_and_probabilities(name: str) -> None:
    est = _estimator(name)
    x = inputs_of(est)
    task = get_task(_scene(est).task)
    assert est.is_classifier == (task.name == "thermal")
    if not est.is_classifier:
        assert not hasattr(est, "predict_proba") or isinstance(est, OnnxEstimator)
        return
    proba = est.predict_proba(x)  # type: ignore[attr-defined]
    labels = est.predict(x)
    assert proba.shape == (len(x), len(task.output_labels(_scene(est))))
    np.testing.assert_allclose(proba.sum(axis=1), 1.0, rtol=1e-5)
    assert labels.dtype == np.int64 and labels.shape == (len(x),)
    assert np.array_equal(labels, proba.argmax(axis=1))
    assert est.predict(x[:0]).shape == (0,)


@pytest.mark.parametrize("name", NAMES)
def test_backend_is_a_constructor_parameter(name: str) -> None:
    est = _estimator(name)
    params = est.get_params()
    if est.kind == "classical":
        assert est.backend == "numpy" and "backend" not in params
        return
    assert params["backend"] == est.backend
    relabelled = type(est)(**{**params, "backend": "onnxruntime-test"})
    assert relabelled.backend == "onnxruntime-test"


def test_torch_network_obeys_the_same_rules() -> None:
    pytest.importorskip("torch", reason="torch is needed for the torch-eager backend")
    from tactile_learn.torch_estimator import TorchEstimator

    weights = ROOT / "models" / "strips5.pt"
    assert weights.is_file(), "models/strips5.pt is shipped beside strips5.onnx"
    est = TorchEstimator.from_checkpoint(weights, threads=1, backend="torch-eager-1t")
    assert est.backend == "torch-eager-1t" and est.get_params()["backend"] == "torch-eager-1t"
    x = inputs_of(est)
    before = fingerprint(vars(est))
    est.predict(x)
    assert fingerprint(vars(est)) == before
    with pytest.raises(NotPreparedError):
        TorchEstimator(est.net, est.task_name, est.scene).predict(x)
