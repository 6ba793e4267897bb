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
3. Turn ``f_ij`` back into pressure through the piezoresistive law (unit gain assumed), with
   ``f_ij`` capped at ``max_share`` (0.95, i.e. 19 ``p0`` for the linear law). Why a cap: a strip's
   load sums the fractions of all its segments, so when two or three contacts load one row and
   one column over several segments the product rule's share exceeds 1, which no single crossing
   can carry; the law's inverse ``p0 ((1 - f)^(-1/n) - 1)`` then diverges (its clip at
   ``1 - 1e-6`` gave 10^8 kPa on 3 in 1,000 three-sphere frames). Near ``f = 1`` the inverse
   amplifies an error in ``f`` by ``1 / (1 - f)^(1 + 1/n)`` - 400x at 0.95 for ``n = 1`` -, so a
   share this high says "very high", not how high.

Ghosts are inherent: two contacts light two rows and two columns, and the product lights all four
crossings. The depth blur of the cover is not undone (see ``projection``). Other layouts
(``synth.sensors.strip_layouts``) enter through their row and column totals only; ``projection``
uses every channel.

A single frame (batch 1, the streaming case) takes :class:`FrameLoads`: the same arithmetic with
the readout's constants folded in ``prepare`` and a dozen in-place ufunc calls on one vector (at
batch 1 the cost is the number of numpy calls, not the arithmetic). Its maps equal the batch
path's to float64 rounding before the cast to float32.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from synth.errors import ConfigError
from synth.scene import Scene
from synth.sensors.strips import StripSensor
from tactile_learn.estimators.base import Estimator
from tactile_learn.validation.strips import strips_check

__all__ = ["FrameLoads", "IntersectionEstimator", "channel_loads", "strip_loads"]


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


@dataclass(frozen=True)
class FrameLoads:
    """:func:`channel_loads` of one frame of an orthogonal layout whose readouts are all dividers,
    with the readout's constants folded: ``divider = v / gain + (V_unloaded - offset / gain)``,
    clipped as :meth:`~synth.sensors.strips.physics.StripReadout.resistance` clips it, then
    ``1 - R / R0 = (1 + Rref / R0) - (Rref V / R0) / divider``, clipped to [0, 1], times the strip's
    segments, zero under the noise floor. Equal to the batch path's loads to float64 rounding."""

    inv_gain: float
    divider_offset: float
    divider_low: float
    divider_high: float
    share_constant: float
    share_scale: float
    segments: np.ndarray  # (C,) float64
    floor: np.ndarray  # (C,) float64: noise_floor x the load noise

    @classmethod
    def of(cls, sensor: StripSensor, floor: np.ndarray) -> FrameLoads | None:
        """The folded constants of ``sensor``; ``None`` where a channel reads linearly (two-ended
        strips) or the layout is not the orthogonal pair (those go through the batch path)."""
        if not sensor.layout.orthogonal or sensor.layout.linear.any():
            return None
        c = sensor.config.readout
        readout = sensor.readout
        r0 = sensor.config.piezo.strip_resistance_ohm
        return cls(
            inv_gain=1.0 / c.amplifier_gain,
            divider_offset=float(readout.v_unloaded) - c.offset_v / c.amplifier_gain,
            divider_low=1e-9 * c.supply_v,
            divider_high=c.supply_v * (1 - 1e-9),
            share_constant=1.0 + c.reference_ohm / r0,
            share_scale=c.reference_ohm * c.supply_v / r0,
            segments=np.asarray(sensor.layout.segments, dtype=np.float64),
            floor=np.asarray(floor, dtype=np.float64),
        )

    def __call__(self, reading: np.ndarray) -> np.ndarray:
        """Loads (C,) float64 of one frame's readings (C,)."""
        v = np.multiply(reading, self.inv_gain, dtype=np.float64)
        v += self.divider_offset
        np.maximum(v, self.divider_low, out=v)
        np.minimum(v, self.divider_high, out=v)
        np.divide(self.share_scale, v, out=v)
        np.subtract(self.share_constant, v, out=v)
        np.maximum(v, 0.0, out=v)
        np.minimum(v, 1.0, out=v)
        v *= self.segments
        v[v <= self.floor] = 0.0
        return v


class IntersectionEstimator(Estimator):
    task = "strips"
    name = "intersection"

    def __init__(
        self,
        scene: Scene,
        rule: Literal["product", "geometric"] = "product",
        noise_floor: float = 2.0,
        max_share: float = 0.95,
    ) -> None:
        self.scene = scene
        self.rule = rule
        self.noise_floor = noise_floor
        self.max_share = max_share

    def prepare(self, sensor: StripSensor | None = None) -> IntersectionEstimator:
        """Build the scene's strip sensor (its readout inverse and noise), once; ``sensor``: one
        already built for the same scene (shared with another method)."""
        if "sensor_" not in self.__dict__:
            if not 0.0 < self.max_share < 1.0:
                raise ConfigError(f"max_share: {self.max_share!r} is not in (0, 1) (a crossing's share of its strips)")
            self.input_check_ = strips_check(self.scene.sensor)
            self.sensor_ = sensor if sensor is not None else StripSensor(self.scene.sensor)
            self.load_floor_ = self.noise_floor * self.sensor_.load_noise()  # per channel, (C,)
            self.frame_loads_ = FrameLoads.of(self.sensor_, self.load_floor_)
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        return self.predict_checked(self.prepared_state("input_check_")(X))

    def predict_checked(self, readings: np.ndarray) -> np.ndarray:
        sensor: StripSensor = self.prepared_state("sensor_")
        frame_loads: FrameLoads | None = self.frame_loads_
        if len(readings) == 1 and frame_loads is not None and self.rule == "product":
            return self._one_frame(frame_loads(readings[0]), sensor)
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
        return sensor.law.stress_from_gain(np.minimum(share, self.max_share)).astype(np.float32)

    def _one_frame(self, loads: np.ndarray, sensor: StripSensor) -> np.ndarray:
        """The product rule on one frame's loads (C,): a (1, N, M) float32 map."""
        n, m = sensor.n_rows, sensor.n_cols
        total = 0.5 * float(loads.sum())
        if total <= 0:  # an idle frame: a zero map, not 0/0
            return np.zeros((1, n, m), dtype=np.float32)
        share = np.multiply.outer(loads[:n] / total, loads[n:])  # >= 0: the clip's floor holds
        # stress_from_gain in place: p0 expm1(-log1p(-min(f, max_share)) / n)
        law = sensor.law
        np.minimum(share, self.max_share, out=share)
        np.negative(share, out=share)
        np.log1p(share, out=share)
        share *= -1.0 / law.exponent
        np.expm1(share, out=share)
        share *= law.p0_kpa
        return share.astype(np.float32).reshape(1, n, m)
