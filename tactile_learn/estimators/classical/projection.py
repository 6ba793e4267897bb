"""Projection-consistent refinement of the intersection estimate.

The intersection estimate ignores how the cover spreads load between neighbouring strips and
does not reproduce the readings it came from. This estimator looks for a non-negative map ``x`` of
cell pressures whose *forward model* - the same cover kernel and piezoresistive law the simulator
uses, with unit gains - reproduces the measured strip loads ``L``:

    minimise  || L_model(x) - L ||^2  over  x >= 0,   starting from the intersection estimate.

Iterations are multiplicative (ISRA, the image-space reconstruction algorithm for non-negative
inverse problems): ``x <- x * (J^T L) / (J^T L_model(x))`` with ``J = dL_model/dx >= 0``. They keep
``x`` non-negative, never light a cell that the starting estimate left dark, and sharpen the
blurred start towards what the readings allow. The problem is underdetermined (N + M equations,
N M unknowns), so the start acts as the prior and the stopping rule as the regulariser.

Stopping rule (per frame): the *discrepancy principle* - stop as soon as the RMS misfit, in units
of the readout noise carried to the loads, is at most ``tau``; fitting the readings more closely
than their noise would fit noise. Also stop when an update changes the map by less than
``rel_tol`` (relative L2) or after ``max_iter`` iterations: a map of cell-constant pressures
cannot represent a contact much smaller than a cell exactly, so for such contacts the misfit
levels off above the noise (typically 20-70 % below the intersection estimate's) and these two
rules end the iterations.
"""

from __future__ import annotations

from functools import cached_property
from typing import Any

import numpy as np

from synth.scene import Scene
from synth.sensors.strips import StripSensor
from tactile_learn.estimators.base import Estimator
from tactile_learn.estimators.classical.intersection import IntersectionEstimator, strip_loads

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

    @cached_property
    def model_(self) -> dict[str, Any]:
        sensor = StripSensor(self.scene.sensor)
        k_row, k_col = sensor.array.cell_stress_operators()
        return {
            "sensor": sensor,
            "k_row": k_row.T.astype(np.float32).copy(),  # right-multiplied: (B, NM) @ (NM, NM)
            "k_col": k_col.T.astype(np.float32).copy(),
            "k_row_t": k_row.astype(np.float32).copy(),
            "k_col_t": k_col.astype(np.float32).copy(),
            "noise": sensor.load_noise().astype(np.float64),
            "start": IntersectionEstimator(self.scene, noise_floor=self.noise_floor),
        }

    def _loads(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Model loads (B, N), (B, M) of cell pressures ``x`` (B, N*M) and the derivative of each
        segment's conductance share (B, N, M) per layer."""
        m = self.model_
        sensor: StripSensor = m["sensor"]
        n, mm = sensor.n_rows, sensor.n_cols
        law = sensor.law
        s_row = np.maximum(x @ m["k_row"], 0.0).reshape(-1, n, mm)
        s_col = np.maximum(x @ m["k_col"], 0.0).reshape(-1, n, mm)
        f_row, f_col = law.conductance_gain(s_row), law.conductance_gain(s_col)
        # df/dp = n / p0 * (1 + p/p0)^(-n-1) = n / p0 * (1 - f)^((n+1)/n)
        power = (law.exponent + 1.0) / law.exponent
        d_row = law.exponent / law.p0_kpa * (1.0 - f_row) ** power
        d_col = law.exponent / law.p0_kpa * (1.0 - f_col) ** power
        return f_row.sum(axis=2), f_col.sum(axis=1), d_row, d_col

    def _jt(self, v_row: np.ndarray, v_col: np.ndarray, d_row: np.ndarray, d_col: np.ndarray) -> np.ndarray:
        """``J^T [v_row; v_col]`` as a flat (B, N*M) map."""
        m = self.model_
        b = len(v_row)
        g_row = (v_row[:, :, None] * d_row).reshape(b, -1)
        g_col = (v_col[:, None, :] * d_col).reshape(b, -1)
        return g_row @ m["k_row_t"] + g_col @ m["k_col_t"]

    def predict(self, X: np.ndarray) -> np.ndarray:
        m = self.model_
        sensor: StripSensor = m["sensor"]
        start = m["start"].predict(X)  # validates X
        b, n, mm = start.shape
        rows, cols = strip_loads(sensor, np.asarray(X, dtype=np.float32), self.noise_floor)
        noise = m["noise"]
        x = start.reshape(b, n * mm).astype(np.float64)
        active = np.flatnonzero(x.max(axis=1) > 0)  # all-zero frames are already consistent
        for _ in range(self.max_iter):
            if active.size == 0:
                break
            xa = x[active]
            lr, lc, d_row, d_col = self._loads(xa.astype(np.float32))
            misfit = np.concatenate([lr - rows[active], lc - cols[active]], axis=1) / noise[None, :]
            rms = np.sqrt(np.mean(misfit**2, axis=1))
            numerator = self._jt(rows[active], cols[active], d_row, d_col)
            denominator = self._jt(lr, lc, d_row, d_col)
            # 0/0 where a cell has no sensitivity left: keep its value
            ratio = np.divide(numerator, denominator, out=np.ones_like(numerator), where=denominator > 1e-30)
            updated = xa * ratio
            change = np.linalg.norm(updated - xa, axis=1) / np.maximum(np.linalg.norm(xa, axis=1), 1e-30)
            go_on = (rms > self.tau) & (change > self.rel_tol)
            # frames that already meet the discrepancy principle keep their current map
            x[active[go_on]] = updated[go_on]
            active = active[go_on]
        return x.reshape(b, n, mm).astype(np.float32)
