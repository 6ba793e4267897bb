"""The one-press check's screen (``OnePressCheck.p_one_press(..., screen)``): the half-space
triangulation hands the check the fitted kernel's solution of the same loads, tried as it is
before the refinements. It only adds a way to pass, so it must leave the flags as they were (on
single presses, two presses and flat indenters, batch and single frames alike) while sparing the
refinement of most genuine presses."""

from __future__ import annotations

import dataclasses
from functools import partial
from typing import Any

import numpy as np
import pytest

from synth.config import replace
from synth.scene import Scene, load_scene
from synth.sensors import fsr
from tactile_learn.estimators.classical.triangulation import FittedTriangulationEstimator, TriangulationEstimator
from tactile_learn.fsr_check import one_press_check
from tactile_learn.fsr_one_frame import OneFrameCheck

SCENE = load_scene("fsr6")


def _scene(**stimulus: object) -> Scene:
    config = SCENE.sensor
    for key, value in {"no_contact_fraction": 0.0, "inside_fraction": 1.0, **stimulus}.items():
        config = replace(config, f"stimulus.{key}", value)
    return dataclasses.replace(SCENE, sensor=config)


def _readings() -> np.ndarray:
    """Single presses (fsr6), two presses and flat indenters, a held-out seed."""
    parts = [fsr.make_simulator(SCENE).simulate(300, np.random.default_rng(91))["readings"]]
    for seed, kind in ((92, "second_press_fraction"), (93, "flat_fraction")):
        parts.append(fsr.make_simulator(_scene(**{kind: 1.0})).simulate(200, np.random.default_rng(seed))["readings"])
    return np.ascontiguousarray(np.concatenate(parts), dtype=np.float32)


READINGS = _readings()


def _unscreened(est: TriangulationEstimator, readings: np.ndarray) -> np.ndarray:
    """The estimator's flags with the check run on its own estimate only (no screen)."""
    estimate = est.predict_batch(readings)[:, :5]
    return est.check_.p_one_press(readings, estimate)


def test_the_screen_leaves_the_flags_as_they_were() -> None:
    """Large batches (the screen after the refinement from the estimate), small batches (before
    the refinements) and single frames (first): the flags without a screen."""
    est = TriangulationEstimator(SCENE).prepare()
    assert est.screen_model_ is not None
    unscreened = _unscreened(est, READINGS)
    screened = est.predict(READINGS)
    small = np.concatenate([est.predict(READINGS[i : i + 8]) for i in range(0, len(READINGS), 8)])
    single = np.concatenate([est.predict(READINGS[i : i + 1]) for i in range(len(READINGS))])
    for flags in (screened, small, single):
        np.testing.assert_array_equal(flags[:, 5], unscreened)
    # the frames cover every verdict, and two presses are caught at all
    assert {0.0, 0.5, 1.0} <= set(unscreened.tolist())
    assert (unscreened[300:500][screened[300:500, 3] > 0.5] == 0.0).mean() > 0.2


def test_the_screen_spares_most_refinements(monkeypatch: pytest.MonkeyPatch) -> None:
    """Genuine presses on single frames: without the screen nearly every one the check reaches
    is refined (the half-space estimate is a poor start); with it, few are."""
    est = TriangulationEstimator(SCENE).prepare()
    presses = READINGS[:300]
    refined: list[int] = []
    original = OneFrameCheck.refined_misfit

    def counted(self: OneFrameCheck, *args: Any, **kwargs: Any) -> float:
        refined.append(1)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(OneFrameCheck, "refined_misfit", counted)
    estimate = est.predict_batch(presses)
    for frame, row in zip(presses, estimate, strict=True):
        est.check_.one_frame.p_one_press(frame.tolist(), row[:5].tolist())
    without = len(refined)
    refined.clear()
    for i in range(len(presses)):
        est.predict(presses[i : i + 1])
    checked = int(((estimate[:, 3] > 0.5) & (estimate[:, 4] > 0.5)).sum())
    assert without >= 0.8 * checked > 50
    assert len(refined) <= 0.3 * without


def _rows_of(points: np.ndarray, rows: np.ndarray) -> np.ndarray:
    return points[rows]


def test_a_screen_on_one_frame_equals_the_batch_screen() -> None:
    """The check with a screen, single frames and small batches against a large batch (a screen
    point off by a few mm on half the frames, so that both outcomes of the screen occur)."""
    check = one_press_check(SCENE).prepare()
    est = TriangulationEstimator(SCENE).prepare()
    estimate = est.predict_batch(READINGS)[:, :5]
    point = FittedTriangulationEstimator(SCENE).prepare().predict_batch(READINGS)[:, :3].copy()
    point[::2, :2] += np.random.default_rng(4).normal(0.0, 3.0, (len(point[::2]), 2)).astype(np.float32)
    batch = check.p_one_press(READINGS, estimate, partial(_rows_of, point))
    small = [
        check.p_one_press(READINGS[i : i + 16], estimate[i : i + 16], partial(_rows_of, point[i : i + 16]))
        for i in range(0, len(READINGS), 16)
    ]
    single = [
        check.one_frame.p_one_press(f.tolist(), e.tolist(), p.tolist())
        for f, e, p in zip(READINGS, estimate, point, strict=True)
    ]
    np.testing.assert_array_equal(single, batch)
    np.testing.assert_array_equal(np.concatenate(small), batch)
    np.testing.assert_array_equal(batch, check.p_one_press(READINGS, estimate))  # same flags as unscreened


def test_the_fitted_kernel_needs_no_screen() -> None:
    """triangulation_fit's own estimate is the fitted kernel's solution: no second one."""
    est = FittedTriangulationEstimator(SCENE).prepare()
    assert est.screen_model_ is None and est.screen_one_frame_ is None
