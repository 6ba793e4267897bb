"""Projection-consistent refinement of the intersection estimate, over every channel of the layout.

The intersection estimate ignores how the cover spreads load between neighbouring strips, uses
only the row and column totals, and does not reproduce the readings it came from. This estimator
looks for a non-negative map ``x`` of cell pressures whose *forward model* - the same cover kernel
per layer and piezoresistive law the simulator uses, with unit gains, and the layout's channel
weights (``synth.sensors.strip_layouts``: whole strips, diagonal strips, two-ended strips' ends,
tapped sections) - reproduces every measured channel load ``L``:

    minimise  || L_model(x) - L ||^2  over  x >= 0,   starting from the intersection estimate.

Iterations are multiplicative (ISRA, the image-space reconstruction algorithm for non-negative
inverse problems): ``x <- x * (J^T L) / (J^T L_model(x))`` with ``J = dL_model/dx >= 0``. They keep
``x`` non-negative, never light a cell that the starting estimate left dark, and sharpen the
blurred start towards what the readings allow: with a diagonal layer or a two-ended readout the
channels that see a ghost crossing but no real contact pull it down. The problem is
underdetermined for the orthogonal pair (N + M equations, N M unknowns), so the start acts as the
prior and the stopping rule as the regulariser.

Stopping rule (per frame): the *discrepancy principle* - stop as soon as the RMS misfit, in units
of the readout noise carried to the loads, is at most ``tau``; fitting the readings more closely
than their noise would fit noise. Also stop when an update changes the map by less than
``rel_tol`` (relative L2) or after ``max_iter`` iterations: a map of cell-constant pressures
cannot represent a contact much smaller than a cell exactly, so for such contacts the misfit
levels off above the noise (typically 20-70 % below the intersection estimate's) and these two
rules end the iterations.

A single frame (batch 1, the streaming case) iterates over its *lit cells* only: the iterations
never light a cell the start left dark, so only the rows of the cover operators that belong to
lit cells matter (a two-contact frame lights a few dozen of 256). ``prepare`` stacks every layer's
operator into one ``(N M, L N M)`` matrix; a frame gathers its lit rows once (``G``), and each
iteration is ``x @ G`` for the stresses and one ``(2, L N M) @ G^T`` for both halves of the ratio,
with ``measured @ w`` computed once per frame: a few dozen numpy calls on short vectors instead of
four ``256 x 256`` products per iteration. The arithmetic and stopping rules are the batch path's
(float32 products, float64 map and misfit), so the maps agree to float32 rounding of the sums
(where rounding moves a frame across a stopping threshold, by at most one iteration's change).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from synth.scene import Scene
from synth.sensors.strips import StripSensor
from tactile_learn.estimators.base import Estimator
from tactile_learn.estimators.classical.intersection import IntersectionEstimator, channel_loads
from tactile_learn.validation.strips import strips_check

__all__ = ["ProjectionEstimator"]


class ProjectionEstimator(Estimator):
    task = "strips"
    name = "projection"

    def __init__(
        self,
        scene: Scene,
        max_iter: int = 60,
        tau: float = 1.0,
        rel_tol: float = 1e-4,
        noise_floor: float = 2.0,
    ) -> None:
        self.scene = scene
        self.max_iter = max_iter
        self.tau = tau
        self.rel_tol = rel_tol
        self.noise_floor = noise_floor

    def prepare(self, sensor: StripSensor | None = None) -> ProjectionEstimator:
        """Build the strip sensor, its cell operators and the starting method, once; ``sensor``:
        one already built for the same scene."""
        if "model_" not in self.__dict__:
            self.input_check_ = strips_check(self.scene.sensor)
            sensor = sensor if sensor is not None else StripSensor(self.scene.sensor)
            ops = sensor.array.layer_cell_operators()
            self.model_: dict[str, Any] = {
                "sensor": sensor,
                "k": [op.T.astype(np.float32).copy() for op in ops],  # right-multiplied: (B, NM) @ (NM, NM)
                "k_t": [op.astype(np.float32).copy() for op in ops],
                "w": sensor.layout.flat_weights.astype(np.float32),  # (C, L*NM)
                "w_t": np.ascontiguousarray(sensor.layout.flat_weights.T, dtype=np.float32),
                "noise": sensor.load_noise().astype(np.float64),
                "start": IntersectionEstimator(self.scene, noise_floor=self.noise_floor).prepare(sensor),
                # every layer's operator side by side: x @ stacked is the stress on every segment
                "stacked": np.ascontiguousarray(np.concatenate([op.T for op in ops], axis=1), dtype=np.float32),
            }
        return self

    def _loads(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Model channel loads (B, C) of cell pressures ``x`` (B, N*M) and the derivative of each
        segment's conductance share (B, L*N*M)."""
        m = self.model_
        law = m["sensor"].law
        stress = np.concatenate([np.maximum(x @ k, 0.0) for k in m["k"]], axis=1)
        f = law.conductance_gain(stress)
        # df/dp = n / p0 * (1 + p/p0)^(-n-1) = n / p0 * (1 - f)^((n+1)/n)
        power = (law.exponent + 1.0) / law.exponent
        d = law.exponent / law.p0_kpa * (1.0 - f) ** power
        return f @ m["w"].T, d

    def _jt(self, v: np.ndarray, d: np.ndarray) -> np.ndarray:
        """``J^T v`` for channel values ``v`` (B, C), as a flat (B, N*M) map."""
        m = self.model_
        back = (v.astype(np.float32) @ m["w"]) * d  # (B, L*NM)
        cells = len(m["k_t"][0])
        return sum(back[:, k * cells : (k + 1) * cells] @ kt for k, kt in enumerate(m["k_t"]))

    def predict(self, X: np.ndarray) -> np.ndarray:
        return self.predict_checked(self.prepared_state("input_check_")(X))

    def predict_checked(self, readings: np.ndarray) -> np.ndarray:
        m: dict[str, Any] = self.prepared_state("model_")
        sensor: StripSensor = m["sensor"]
        intersection: IntersectionEstimator = m["start"]
        start = intersection.predict_checked(readings)
        b, n, mm = start.shape
        if b == 1 and intersection.frame_loads_ is not None:
            # the same loads as channel_loads, through the single-frame arithmetic
            return self._one_frame(start, intersection.frame_loads_(readings[0]))
        measured = channel_loads(sensor, readings, self.noise_floor, intersection.load_floor_)
        if b == 1:
            return self._one_frame(start, measured[0])
        noise = m["noise"]
        x = start.reshape(b, n * mm).astype(np.float64)
        active = np.flatnonzero(x.max(axis=1) > 0)  # all-zero frames are already consistent
        for _ in range(self.max_iter):
            if active.size == 0:
                break
            xa = x[active]
            model, d = self._loads(xa.astype(np.float32))
            misfit = (model - measured[active]) / noise[None, :]
            rms = np.sqrt(np.mean(misfit**2, axis=1))
            numerator = self._jt(measured[active], d)
            denominator = self._jt(model, d)
            # 0/0 where a cell has no sensitivity left: keep its value
            ratio = np.divide(numerator, denominator, out=np.ones_like(numerator), where=denominator > 1e-30)
            updated = xa * ratio
            change = np.linalg.norm(updated - xa, axis=1) / np.maximum(np.linalg.norm(xa, axis=1), 1e-30)
            go_on = (rms > self.tau) & (change > self.rel_tol)
            # frames that already meet the discrepancy principle keep their current map
            x[active[go_on]] = updated[go_on]
            active = active[go_on]
        return x.reshape(b, n, mm).astype(np.float32)

    def _one_frame(self, start: np.ndarray, measured: np.ndarray) -> np.ndarray:
        """:meth:`predict_checked`'s iterations for one frame (its start (1, N, M), its channel
        loads (C,)) over the cells the start lights (module docstring)."""
        m: dict[str, Any] = self.model_
        flat = start.reshape(-1)
        lit = np.flatnonzero(flat)
        if not len(lit):
            return start  # an all-zero frame is already consistent
        law = m["sensor"].law
        exponent, p0 = law.exponent, law.p0_kpa
        power = (exponent + 1.0) / exponent
        w: np.ndarray = m["w"]
        w_t: np.ndarray = m["w_t"]
        inv_noise = 1.0 / m["noise"]
        g = m["stacked"][lit]  # (lit, L N M): the rows of the lit cells
        g_t = np.ascontiguousarray(g.T)
        sides = np.empty((2, w.shape[1]), dtype=np.float32)
        weighted = np.empty_like(sides)
        # np.dot: a vector times a matrix without matmul's generalised-ufunc set-up (2 us a call here)
        np.dot(measured.astype(np.float32), w, out=sides[0])  # J^T's numerator side, fixed per frame
        x = flat[lit].astype(np.float64)
        ratio = np.empty(len(lit), dtype=np.float32)
        for _ in range(self.max_iter):
            stress = np.dot(x.astype(np.float32), g)
            np.maximum(stress, 0.0, out=stress)
            # the law's conductance_gain and its derivative, as _loads computes them
            stress /= p0
            f = np.log1p(stress, out=stress)
            f *= -exponent
            np.expm1(f, out=f)
            np.negative(f, out=f)
            model = np.dot(f, w_t)
            misfit = (model - measured) * inv_noise
            if not math.sqrt(float(np.dot(misfit, misfit)) / len(misfit)) > self.tau:
                break  # the discrepancy principle is met: keep the current map
            d = np.subtract(1.0, f, dtype=np.float32)
            d **= power
            d *= exponent / p0
            np.dot(model, w, out=sides[1])
            numerator, denominator = np.dot(np.multiply(sides, d, out=weighted), g_t)
            # 0/0 where a cell has no sensitivity left: keep its value
            ratio.fill(1.0)
            np.divide(numerator, denominator, out=ratio, where=denominator > 1e-30)
            updated = x * ratio
            step = updated - x
            if not math.sqrt(float(np.dot(step, step))) > self.rel_tol * max(math.sqrt(float(np.dot(x, x))), 1e-30):
                break  # the map has settled
            x = updated
        out = np.zeros_like(flat)
        out[lit] = x
        return out.reshape(start.shape)
