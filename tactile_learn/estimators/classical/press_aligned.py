"""Few-shot classifier of real touches that times the contact by the press (the force record).

Why: a robot presses at different speeds in different sessions (on the thermal-robot recordings
the force rises in 0.3 s in one session, 1.2-1.8 s in the others). While the contact builds up,
the heat flow follows the contact conductance, which follows the force; a curve read against
clock time then mixes the material with the press speed, and a classifier trained on one
session's presses fails on another's. Read against *press time*,

    tau(t) = integral from the first touch to t of F(t') / F_plateau dt'    (t after the first touch)
    tau(t) = t - t_first_touch                                              (before it)

a slow press and a fast one give nearly the same curve (the flux through a conductance that grows
with the force has moved the same heat at the same tau), so the shape is the material's.

Features per touch, on a grid of ``points`` press times from ``-PRE_S`` to the duration read:
the heated curve minus its value at the first touch, divided by its drop at the end (its *shape*:
how early the drop comes relative to the press separates a cold, poorly conducting object, which
draws most heat while the contact is still light, from a conducting one at room temperature), the
logarithm of that drop (its *size*: wood at room temperature draws little heat), weighted
``amplitude_weight`` times, and every other channel's curve minus its value at the first touch
(the passive thermistor, read as is: its drop is ~0 except on cooled objects). The classes may be
multimodal (wood at room temperature and cooled wood share the label ``wood``), so the classifier
is the nearest labelled touch after standardising each feature (a class mean or a linear rule
would average the two modes). ``points`` = 9 and ``amplitude_weight`` = 3 were chosen by
leave-one-out on the 9 labelled touches of R_1 (docs/thermal-real.md). numpy only.
"""

from __future__ import annotations

import numpy as np

from tactile_learn.estimators.classical.aligned_pca import PRE_S
from tactile_learn.estimators.classical.curve_match import softmax

__all__ = ["FIRST_TOUCH", "NearestTouch", "press_aligned_features", "press_time"]

#: the first touch: where the filtered force first reaches this fraction of its plateau
FIRST_TOUCH = 0.05
#: the smallest drop (K) read as a drop: below the thermistors' resolution a curve has no shape
MIN_DROP_K = 1e-4


def press_time(press: np.ndarray, has_press: np.ndarray, onset_s: np.ndarray, fs: float) -> np.ndarray:
    """Press time (N, R) in seconds for records sampled at ``fs`` from 0: the running integral of
    ``press`` (force / plateau, :func:`~tactile_learn.thermal_recordings.press_profile`) from the
    first touch, clock time before it; clock time from the onset where a record has no force."""
    press = np.clip(np.asarray(press, dtype=np.float64), 0.0, None)  # a negative force pushes no heat
    n, r = press.shape
    t = np.arange(r) / fs
    tau = np.empty((n, r))
    for i in range(n):
        touched = press[i] >= FIRST_TOUCH
        if not has_press[i] or not touched.any():
            tau[i] = t - onset_s[i]
            continue
        k = int(np.argmax(touched))
        step = 0.5 * (press[i, 1:] + press[i, :-1]) / fs
        after = np.concatenate([[0.0], np.cumsum(step[k:])])
        tau[i, :k] = t[:k] - t[k]
        tau[i, k:] = after
    return tau


def _at(tau: np.ndarray, values: np.ndarray, grid: np.ndarray) -> np.ndarray:
    # tau never decreases (the press is clipped at 0); equal steps while the force reads 0 are fine
    return np.interp(grid, tau, values)


def press_aligned_features(
    records: list[np.ndarray],
    press: np.ndarray,
    has_press: np.ndarray,
    onset_s: np.ndarray,
    fs: float,
    duration_s: float,
    points: int = 9,
    amplitude_weight: int = 3,
) -> np.ndarray:
    """Features (N, F) of the touches whose channels are ``records`` (heated first, each (N, R),
    sampled at ``fs`` from 0), read up to ``duration_s`` after ``onset_s``: see the module."""
    if points < 2:
        raise ValueError(f"points must be at least 2, got {points}")
    tau = press_time(press, has_press, onset_s, fs)
    grid = np.linspace(-PRE_S, duration_s, points)
    rows = []
    for i in range(len(tau)):
        end = min(int(np.floor((onset_s[i] + duration_s) * fs)) + 1, tau.shape[1])
        curves = [np.asarray(rec[i, :end], dtype=np.float64) for rec in records]
        at = [_at(tau[i, :end], c, grid) - _at(tau[i, :end], c, np.zeros(1)) for c in curves]
        drop = max(abs(float(at[0][-1])), MIN_DROP_K)
        rows.append(np.concatenate([at[0] / drop, np.full(amplitude_weight, np.log(drop)), *at[1:]]))
    return np.array(rows)


class NearestTouch:
    """The nearest labelled touch after standardising each feature; ``fit`` then ``predict_proba``
    (a softmax of minus half the squared distance to each class's nearest touch, per feature)."""

    def fit(self, x: np.ndarray, y: np.ndarray, n_classes: int) -> NearestTouch:
        x = np.asarray(x, dtype=np.float64)
        self.mean_ = x.mean(axis=0)
        self.scale_ = np.maximum(x.std(axis=0), 1e-9)  # a constant feature (the first touch) divides nothing
        self.train_ = (x - self.mean_) / self.scale_
        self.labels_ = np.asarray(y, dtype=np.int64)
        self.n_classes_ = n_classes
        return self

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        z = (np.asarray(x, dtype=np.float64) - self.mean_) / self.scale_
        d2 = ((z[:, None, :] - self.train_[None, :, :]) ** 2).mean(axis=2)
        score = np.full((len(z), self.n_classes_), -np.inf)
        for k in range(self.n_classes_):
            if (self.labels_ == k).any():
                score[:, k] = -0.5 * d2[:, self.labels_ == k].min(axis=1)
        return softmax(score)
