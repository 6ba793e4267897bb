"""The seed paper's strip-intersection algorithm.

1. Invert each strip's readout to its *load* ``L`` - the sum over its segments of the fraction of
   segment resistance that pressure removes (``synth.sensors.strips.StripSensor.invert_readings``).
   Loads below ``noise_floor`` standard deviations of the readout noise are set to zero.
2. Estimate intersection ``(i, j)`` from its row load ``Lr_i`` and column load ``Lc_j`` by the
   *normalised product* ``f_ij = Lr_i Lc_j / T`` with ``T = (sum Lr + sum Lc) / 2``.
   Why this rule: it is the maximum-entropy map whose row and column sums are the measured loads
   (both marginals are kept when the two totals agree), it is exact for a single contact inside one
   cell, and unlike the geometric mean ``sqrt(Lr_i Lc_j)`` it does not spread a strong row over every
   lit column. (``rule="geometric"`` is available for comparison.)
3. Turn ``f_ij`` back into pressure through the piezoresistive law (unit gain assumed).

Ghosts are inherent: two contacts light two rows and two columns, and the product lights all four
crossings. The depth blur of the cover is not undone (see ``projection``). Other layouts
(``synth.sensors.strip_layouts``) enter through their row and column totals only; ``projection``
uses every channel.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from synth.scene import Scene
from synth.sensors.strips import StripSensor
from tactile_learn.estimators.base import Estimator
from tactile_learn.validation.strips import strips_check

__all__ = ["IntersectionEstimator", "channel_loads", "strip_loads"]


def channel_loads(
    sensor: StripSensor, readings: np.ndarray, noise_floor: float, floor: np.ndarray | None = None
) -> np.ndarray:
    """Every channel's load (B, C), float64, with loads under the noise floor zeroed; ``floor``: the
    per-channel threshold ``noise_floor * sensor.load_noise()`` when the caller has it already (its
    readout inversions cost more than a frame's arithmetic at batch 1)."""
    loads = sensor.invert_readings(readings)
    if floor is None:
        floor = noise_floor * sensor.load_noise()
    return np.where(loads > floor[None, :], loads, 0.0)


def strip_loads(
    sensor: StripSensor, readings: np.ndarray, noise_floor: float, floor: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Row and column loads (B, N), (B, M), float64, with loads under the noise floor zeroed (any
    layout: a two-ended strip's ends, a tapped strip's sections summed; diagonal strips left out)."""
    loads = channel_loads(sensor, readings, noise_floor, floor)
    if sensor.layout.orthogonal:
        return loads[:, : sensor.n_rows], loads[:, sensor.n_rows :]
    return sensor.layout.row_col_loads(loads)


class IntersectionEstimator(Estimator):
    task = "strips"
    name = "intersection"

    def __init__(
        self, scene: Scene, rule: Literal["product", "geometric"] = "product", noise_floor: float = 2.0
    ) -> None:
        self.scene = scene
        self.rule = rule
        self.noise_floor = noise_floor

    def prepare(self, sensor: StripSensor | None = None) -> IntersectionEstimator:
        """Build the scene's strip sensor (its readout inverse and noise), once; ``sensor``: one
        already built for the same scene (shared with another method)."""
        if "sensor_" not in self.__dict__:
            self.input_check_ = strips_check(self.scene.sensor)
            self.sensor_ = sensor if sensor is not None else StripSensor(self.scene.sensor)
            self.load_floor_ = self.noise_floor * self.sensor_.load_noise()  # per channel, (C,)
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        return self.predict_checked(self.prepared_state("input_check_")(X))

    def predict_checked(self, readings: np.ndarray) -> np.ndarray:
        sensor: StripSensor = self.prepared_state("sensor_")
        rows, cols = strip_loads(sensor, readings, self.noise_floor, self.load_floor_)
        if self.rule == "product":
            total = 0.5 * (rows.sum(axis=1) + cols.sum(axis=1))
            outer = rows[:, :, None] * cols[:, None, :]
            # an all-zero frame has T = 0: its map is zero, not 0/0
            share = np.divide(outer, total[:, None, None], out=np.zeros_like(outer), where=total[:, None, None] > 0)
        elif self.rule == "geometric":
            share = np.sqrt(rows[:, :, None] * cols[:, None, :])
        else:
            raise ValueError(f"rule: {self.rule!r} is not 'product' or 'geometric'")
        return sensor.law.stress_from_gain(share).astype(np.float32)
