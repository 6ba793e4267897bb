"""The strip array as a :class:`~synth.sensors.model.SensorModel`: cover mechanics -> piezoresistance
and readout -> noise -> ADC (the stages' physics in :mod:`synth.sensors.strips.physics`).

The stimulus is either drawn contacts (:class:`~synth.sensors.strips.stimuli.StripContacts`: the
mechanics runs only over their pressure windows) or a user's pressure field on the whole lattice
(:class:`~synth.sensors.strips.stimuli.PressureField`). Both give the same stress for the same
pressure (``tests/synth/sensors/test_strips_physics.py``).
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from synth.sensors.base import ArraySpec
from synth.sensors.model import SensorModel
from synth.sensors.strips.config import StripsConfig
from synth.sensors.strips.layouts import StripLayout
from synth.sensors.strips.physics import StripSensor
from synth.sensors.strips.stimuli import OUTPUTS, PressureField, StripContacts, contact_pad

__all__ = ["StripModel", "StripStimulus"]

StripStimulus = StripContacts | PressureField


class StripModel(SensorModel[StripStimulus]):
    """One strip array; readings ``(B, C)`` in volts (``C`` channels of the layout).

    Stages: ``physics`` -> mean stress (kPa) on every segment of every strip layer ``(B, L, N, M)``
    (rows, columns, then the diagonal layers); ``transduce`` -> the clean readings (clipped to the
    ADC's range, float32 like the stress); ``noise`` -> Gaussian electrical noise; ``adc`` ->
    quantised and clipped. ``inverse_readout`` gives every channel's load in segment units (unit
    gains), the classical estimators' strip pressure integral.

    ``pad`` (cells of lattice beyond the array on every side) defaults to what the scene's contacts
    can reach. The mechanics of the last stimulus is kept, so the truth drawn from the same frames
    (intersection map, clean readings) does not repeat it.
    """

    def __init__(self, config: StripsConfig, pad: int | None = None) -> None:
        self.config = config
        self.pad = contact_pad(config)[1] if pad is None else pad
        self.layout = StripLayout(config.geometry)
        self._last: tuple[StripStimulus, np.ndarray, np.ndarray] | None = None

    @cached_property
    def sensor(self) -> StripSensor:
        """The stages' physics (built on first use: latent-only scenes need no mechanics)."""
        return StripSensor(self.config, pad=self.pad)

    def loads(self, stimulus: StripStimulus) -> tuple[np.ndarray, np.ndarray]:
        """Segment stress (B, L, N, M) and the intersection map (B, N, M) (kPa, float32) of ``stimulus``."""
        if self._last is not None and self._last[0] is stimulus:
            return self._last[1], self._last[2]
        array = self.sensor.array
        if isinstance(stimulus, PressureField):
            row, col = array.segment_stress(stimulus.field_kpa)
            layers = [row[:, None], col[:, None]]
            if array.diag_ops:
                layers.append(array.diagonal_stress(stimulus.field_kpa))
            cells = array.cell_pressure(stimulus.field_kpa)
        else:
            layers, cells = self._window_loads(stimulus)
        stress = np.concatenate(layers, axis=1)
        self._last = (stimulus, stress, cells)
        return stress, cells

    def _window_loads(self, stimulus: StripContacts) -> tuple[list[np.ndarray], np.ndarray]:
        g = self.config.geometry
        n = len(stimulus)
        shape = (n, g.n_rows, g.n_cols)
        row, col, cells = (np.zeros(shape, np.float32) for _ in range(3))
        n_diag = len(self.layout.layers) - 2
        diag = np.zeros((n, n_diag, g.n_rows, g.n_cols), np.float32) if n_diag else None
        for slots, win in stimulus.windows:
            parts = self.sensor.array.window_products(win)
            # a frame holds at most one window per slot: plain fancy-index adds, no np.add.at needed
            for slot in np.unique(slots[1]):
                sel = slots[1] == slot
                frames = slots[0][sel]
                for key, target in (("row", row), ("col", col), ("cells", cells), ("diag", diag)):
                    if key in parts and target is not None:
                        target[frames] += parts[key][sel]
        # frames without contact keep zero stress: their readings are the baseline; the separable
        # kernel's truncation can leave -1e-6-sized stress far from any load
        layers = [np.maximum(row, 0.0)[:, None], np.maximum(col, 0.0)[:, None]]
        if diag is not None:
            layers.append(np.maximum(diag, 0.0))
        return layers, np.maximum(cells, 0.0)

    def physics(self, stimulus: StripStimulus) -> np.ndarray:
        return self.loads(stimulus)[0]

    def pressure_map(self, stimulus: StripStimulus) -> np.ndarray:
        """Intersection map (B, N, M) float32 kPa: the mean surface pressure over every pitch cell."""
        return self.loads(stimulus)[1]

    def transduce(self, physical: np.ndarray, stimulus: StripStimulus) -> np.ndarray:
        diag = physical[:, 2:] if physical.shape[1] > 2 else None
        clean = self.sensor.clean_readings(physical[:, 0], physical[:, 1], stimulus.gains, diag)
        return clean.astype(np.float32)

    def noise(self, analog: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return self.sensor.noise(analog, rng)

    def adc(self, analog: np.ndarray) -> np.ndarray:
        return self.sensor.adc(analog)

    def inverse_readout(self, readings: np.ndarray) -> np.ndarray:
        """Every channel's load in segment units (B, C), for unit gains (:meth:`StripSensor.invert_readings`)."""
        return self.sensor.invert_readings(readings)

    def reading_spec(self) -> ArraySpec:
        layout, channels = self.layout, self.layout.n_channels
        what = OUTPUTS["readings"] if layout.orthogonal else f"readings (V) of layout {layout.name!r}: ({channels},)"
        return ArraySpec((channels,), "float32", what)
