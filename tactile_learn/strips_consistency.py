"""Does a strip map explain the readings it came from? The readings residual of any estimate.

Push an estimated intersection map (B, N, M) back through the strip array's forward model and
compare the readings it predicts with the measured ones.

The forward model is the simulator's own (``synth.sensors.strips``): Boussinesq's cover kernel,
the piezoresistive law per segment, the series sum per strip and the divider and amplifier, with
one documented approximation and two simplifications:

- **cell-constant pressure** (the approximation): a map gives one pressure per pitch x pitch
  intersection cell, so its pressure is spread uniformly over that cell. The true field varies
  inside a cell; what the cover passes on of that variation is lost, so even the *true* map leaves
  a small residual, largest for contacts much smaller than a cell (a sharp sphere) and for strong
  presses (the piezoresistive law is nonlinear, so the mean of ``f(stress)`` over a segment is not
  ``f`` of its mean stress);
- unit strip gains (a calibrated sensor) and no electrical noise or ADC step.

The residual compares strip *loads* (``StripSensor.invert_readings``: a reading turned into the
sum over its segments of the share of resistance that pressure removed), per frame:

- ``residual_sigma``: the RMS over strips of the load difference in units of each strip's load
  noise (how many noise standard deviations the map leaves unexplained). The flag of the general
  model uses this one: it separates frames unlike the training data best (docs/strips.md);
- ``residual_rel``: the same RMS difference divided by the RMS measured load plus ``noise_floor``
  times the RMS load noise: scale-free (a strong and a weak press of one shape score alike), the
  number ``eval`` reports for every method.

:meth:`StripConsistency.balance` needs no map: the row strips and the column strips carry the same
pressure, so their total loads agree up to the cover's depth difference and the piezoresistive
nonlinearity; a mismatch (a drifted or damaged strip, another sensor) is another sign of a frame
unlike the training data.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from synth.errors import InputError
from synth.scene import Scene
from synth.sensors.strips import StripSensor

__all__ = ["StripConsistency"]


class StripConsistency:
    """The forward model from intersection maps to strip loads and readings, and the residual."""

    def __init__(self, scene: Scene, noise_floor: float = 3.0) -> None:
        self.scene = scene
        self.noise_floor = noise_floor

    @cached_property
    def sensor(self) -> StripSensor:
        return StripSensor(self.scene.sensor)

    @cached_property
    def operators(self) -> list[np.ndarray]:
        """Segment stress of every layer (rows, columns, diagonals) from a flat cell map,
        right-multiplied: (N*M, N*M) each."""
        return [op.T.astype(np.float32).copy() for op in self.sensor.array.layer_cell_operators()]

    @cached_property
    def load_noise(self) -> np.ndarray:
        return self.sensor.load_noise()

    def _maps(self, maps: np.ndarray) -> np.ndarray:
        s = self.sensor
        arr = np.asarray(maps)
        if arr.ndim != 3 or arr.shape[1:] != (s.n_rows, s.n_cols):
            raise InputError(f"maps: expected shape (B, {s.n_rows}, {s.n_cols}), got {arr.shape}")
        if not np.isfinite(arr).all():
            raise InputError("maps: contain NaN or inf")
        # a negative estimate is not a pressure the cover can carry: it pushes nothing
        return np.maximum(arr.reshape(len(arr), -1), 0.0).astype(np.float32)

    def model_loads(self, maps: np.ndarray) -> np.ndarray:
        """Channel loads (B, C) that the maps would produce, in the layout's readings order (the
        orthogonal pair: N + M strips, rows first; see the module docstring)."""
        s = self.sensor
        x = self._maps(maps)
        # the operators' truncated kernel can leave -1e-6-sized stress far from any load
        stress = np.stack([np.maximum(x @ k, 0.0) for k in self.operators], axis=1)
        return s.channel_loads(stress.reshape(len(x), -1, s.n_rows, s.n_cols))

    def model_readings(self, maps: np.ndarray) -> np.ndarray:
        """Noise-free readings (V) the maps would produce, unit gains, clipped to the ADC's range."""
        return np.asarray(self.sensor.readings_from_loads(self.model_loads(maps)), dtype=np.float32)

    def residual(self, readings: np.ndarray, maps: np.ndarray) -> dict[str, np.ndarray]:
        """Per frame: ``residual_rel`` and ``residual_sigma`` (module docstring) of ``maps`` against
        the measured ``readings`` (B, N+M)."""
        from tactile_learn.tasks import get_task

        x = get_task("strips").check_inputs(readings, self.scene)
        if len(x) != len(maps):
            raise InputError(f"maps: {len(maps)} frames for {len(x)} frames of readings")
        measured = self.sensor.invert_readings(x)
        diff = self.model_loads(maps) - measured
        noise = self.load_noise[None, :]
        rms_diff = np.sqrt(np.mean(diff**2, axis=1))
        scale = np.sqrt(np.mean(measured**2, axis=1)) + self.noise_floor * float(np.sqrt(np.mean(noise**2)))
        return {
            "residual_rel": rms_diff / scale,
            "residual_sigma": np.sqrt(np.mean((diff / noise) ** 2, axis=1)),
        }

    def balance(self, readings: np.ndarray) -> np.ndarray:
        """|sum of row loads - sum of column loads| over half their sum plus ``noise_floor`` times
        the noise of a whole layer's total (B,): near 0 for any pressure on a healthy sensor."""
        from tactile_learn.tasks import get_task

        x = get_task("strips").check_inputs(readings, self.scene)
        loads = self.sensor.invert_readings(x)
        row_loads, col_loads = self.sensor.layout.row_col_loads(loads)
        rows, cols = row_loads.sum(axis=1), col_loads.sum(axis=1)
        floor = self.noise_floor * float(np.sqrt(np.sum(self.load_noise**2)))
        return np.asarray(np.abs(rows - cols) / (0.5 * (rows + cols) + floor))
