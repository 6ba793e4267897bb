"""Soft strip array: orthogonal conductive-rubber strips, one reading per strip (other layouts:
diagonal strips, two-ended readout, taps - :mod:`synth.sensors.strips.layouts`).

Physics, from stimulus to reading (every stage is its own object, so tests can check each):

1. **Surface pressure** (kPa) on a fine lattice of ``s = samples_per_pitch`` cells per pitch,
   ``(N s, M s)`` cells of pitch ``h = pitch / s``; cell ``(k, l)`` is centred at
   ``y = (k + 0.5) h``, ``x = (l + 0.5) h`` (``synth.stimuli``).
2. **Stress at depth** (:class:`~synth.sensors.strips.mechanics.StripArray`): Boussinesq's exact
   rectangle kernel at the row strips' depth (``cover_mm``) and the column strips' depth
   (``cover_mm + strip_thickness_mm``), averaged over each strip *segment* - the ``pitch``-long
   piece of a strip at one crossing, across the strip's width (``synth.mechanics``).
3. **Piezoresistance** (:class:`PiezoLaw`): segment resistance ``R_seg (1 + p / (g p0))^(-n)``;
   a strip is the series sum of its segments, so its resistance is a *nonlinear projection* of the
   pressure along it. ``g`` is the strip's sensitivity gain (part-to-part spread).
4. **Readout** (:class:`StripReadout`): divider, auto-zeroed instrumentation amplifier, then
   :class:`GaussianNoise` and the ADC's quantisation and clipping (:class:`Adc`).

Ground truth is the intersection map: the mean *surface* pressure over each ``pitch x pitch``
cell (kPa), and the contact list (:mod:`synth.sensors.strips.stimuli`); the stages as one
:class:`~synth.sensors.model.SensorModel` are :class:`synth.sensors.strips.sensor.StripModel`.
:meth:`StripSensor.forward` answers "what would my sensor read for this pressure field?" for any
user field on the documented lattice.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from synth.errors import InputError
from synth.sensors.strips.config import StripReadout as ReadoutConfig
from synth.sensors.strips.config import StripsConfig
from synth.sensors.strips.mechanics import StripArray

__all__ = [
    "Adc",
    "GaussianNoise",
    "PiezoLaw",
    "StripArray",
    "StripReadout",
    "StripSensor",
]


class PiezoLaw:
    """Power-law piezoresistance of one strip segment: ``R = R_seg (1 + p / (g p0))^(-n)``."""

    def __init__(self, p0_kpa: float, exponent: float) -> None:
        self.p0_kpa = p0_kpa
        self.exponent = exponent

    def conductance_gain(self, stress_kpa: np.ndarray, gain: np.ndarray | float = 1.0) -> np.ndarray:
        """``f = 1 - R/R_seg`` in [0, 1): the fraction of a segment's resistance that pressure removes."""
        # log1p/expm1: accurate for tiny stress, where 1 - (1 + x)^-n would cancel
        x = np.maximum(stress_kpa, 0.0) / (self.p0_kpa * gain)
        return -np.expm1(-self.exponent * np.log1p(x))

    def stress_from_gain(self, f: np.ndarray, gain: np.ndarray | float = 1.0) -> np.ndarray:
        """Inverse of :meth:`conductance_gain` (f clipped to [0, 1 - 1e-6]: beyond, stress is unbounded)."""
        f = np.clip(f, 0.0, 1.0 - 1e-6)
        return self.p0_kpa * gain * np.expm1(-np.log1p(-f) / self.exponent)


class StripReadout:
    """Divider + auto-zeroed amplifier, ideal (noise-free, unquantised)."""

    def __init__(self, config: ReadoutConfig, unloaded_ohm: float) -> None:
        self.config = config
        self.unloaded_ohm = unloaded_ohm
        self.v_unloaded = self._divider(np.float64(unloaded_ohm))

    def _divider(self, resistance: np.ndarray | float) -> np.ndarray:
        c = self.config
        return np.asarray(c.supply_v * c.reference_ohm / (c.reference_ohm + np.asarray(resistance)))

    def volts(self, resistance: np.ndarray) -> np.ndarray:
        """Reading (V) of strips of ``resistance`` (ohm), before noise and the ADC (float64).

        Written as ``divider(R) - divider(R0) = V Rref (R0 - R) / ((Rref + R)(Rref + R0))`` so an
        unloaded strip reads exactly ``offset_v`` instead of a rounding residue of two near-equal
        divider voltages.
        """
        c = self.config
        r = np.asarray(resistance, dtype=np.float64)
        r0 = self.unloaded_ohm
        delta = c.supply_v * c.reference_ohm * (r0 - r) / ((c.reference_ohm + r) * (c.reference_ohm + r0))
        return c.offset_v + c.amplifier_gain * delta

    def resistance(self, volts: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`volts`: strip resistance (ohm) from a reading (V)."""
        c = self.config
        divider = self.v_unloaded + (np.asarray(volts, dtype=np.float64) - c.offset_v) / c.amplifier_gain
        # a reading can sit below what any resistance gives (noise under the offset) or at the supply
        divider = np.clip(divider, 1e-9 * c.supply_v, c.supply_v * (1 - 1e-9))
        return c.reference_ohm * (c.supply_v / divider - 1.0)


@dataclass(frozen=True)
class GaussianNoise:
    sd: float

    def __call__(self, volts: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        if self.sd == 0:
            return volts
        return volts + rng.normal(0.0, self.sd, size=volts.shape).astype(volts.dtype)


@dataclass(frozen=True)
class Adc:
    bits: int
    supply_v: float

    def __call__(self, volts: np.ndarray, quantise: bool = True) -> np.ndarray:
        lsb = self.supply_v / 2**self.bits
        top = 2**self.bits - 1
        if not quantise:
            return np.clip(volts, 0.0, top * lsb)
        return np.clip(np.round(volts / lsb), 0, top) * lsb


class StripSensor:
    """The whole strip array: pressure field -> readings, with each stage exposed."""

    def __init__(self, config: StripsConfig, pad: int = 0) -> None:
        self.config = config
        self.array = StripArray(config, pad)
        self.law = PiezoLaw(config.piezo.p0_kpa, config.piezo.exponent)
        self.readout = StripReadout(config.readout, config.piezo.strip_resistance_ohm)
        self.noise = GaussianNoise(config.readout.noise_v)
        self.adc = Adc(config.readout.adc_bits, config.readout.supply_v)
        g = config.geometry
        self.n_rows, self.n_cols = g.n_rows, g.n_cols
        self.layout = self.array.layout
        #: physical strips (one gain each) and readings (one per channel of the layout)
        self.n_strips = self.layout.n_strips
        self.n_channels = self.layout.n_channels

    @property
    def field_shape(self) -> tuple[int, int]:
        """Lattice of :meth:`forward`'s pressure field: (N*s, M*s) cells of ``field_pitch_mm``."""
        return self.array.field_shape

    @property
    def field_pitch_mm(self) -> float:
        return self.array.h

    def strip_resistance(self, row_stress: np.ndarray, col_stress: np.ndarray, gains: np.ndarray) -> np.ndarray:
        """Series resistance (ohm) of every strip, (B, N+M), rows first."""
        r0 = self.config.piezo.strip_resistance_ohm
        g_row = gains[:, : self.n_rows, None]
        g_col = gains[:, None, self.n_rows :]
        # sum of segment resistances: R0 * (1 - mean_j f_j); f is what pressure removes
        f_row = self.law.conductance_gain(row_stress, g_row).mean(axis=2)
        f_col = self.law.conductance_gain(col_stress, g_col).mean(axis=1)
        return r0 * (1.0 - np.concatenate([f_row, f_col], axis=1))

    def clean_readings(
        self,
        row_stress: np.ndarray,
        col_stress: np.ndarray,
        gains: np.ndarray,
        diag_stress: np.ndarray | None = None,
    ) -> np.ndarray:
        """Noise-free readings (V), clipped to the ADC's range but not quantised; ``diag_stress``
        (B, D, N, M) for the diagonal layers of layout 'diagonal'."""
        if self.layout.orthogonal:
            return self.adc(self.readout.volts(self.strip_resistance(row_stress, col_stress, gains)), quantise=False)
        layers = [row_stress[:, None], col_stress[:, None]]
        if diag_stress is not None:
            layers.append(diag_stress)
        stress = np.concatenate(layers, axis=1)
        if stress.shape[1] != len(self.layout.layers):
            raise ValueError(f"stress of {stress.shape[1]} layers for a layout of {len(self.layout.layers)}")
        return self.readings_from_loads(self.channel_loads(stress, gains))

    def channel_loads(self, stress: np.ndarray, gains: np.ndarray | float = 1.0) -> np.ndarray:
        """Every channel's load (B, C), float64: the weighted sum of the conductance share ``f`` of
        the segments it reads, for stress (B, L, N, M) on every layer and per-strip ``gains``."""
        g = np.asarray(gains, dtype=np.float32)
        segment_gain = g[:, self.layout.segment_strip] if g.ndim == 2 else g
        f = self.law.conductance_gain(stress, segment_gain)
        return f.reshape(len(f), -1).astype(np.float64) @ self.layout.flat_weights.T

    def readings_from_loads(self, loads: np.ndarray) -> np.ndarray:
        """Noise-free readings (V) of channel ``loads`` (B, C), clipped to the ADC's range."""
        c = self.config.readout
        share = loads / self.layout.segments
        series = self.readout.volts(self.config.piezo.strip_resistance_ohm * (1.0 - share))
        linear = c.offset_v + c.amplifier_gain * c.supply_v / 4.0 * share
        return self.adc(np.where(self.layout.linear, linear, series), quantise=False)

    def digitise(self, clean: np.ndarray, rng: np.random.Generator | None, noise: bool = True) -> np.ndarray:
        """Add electrical noise and quantise (``noise=False``: the ideal readout)."""
        if not noise:
            return clean
        if rng is None:
            raise ValueError("a numpy Generator is needed for noisy readings")
        return self.adc(self.noise(clean, rng))

    def forward(
        self,
        field: np.ndarray,
        gains: np.ndarray | None = None,
        rng: np.random.Generator | None = None,
        noise: bool = False,
    ) -> dict[str, np.ndarray]:
        """Readings and intersection map for the user's pressure ``field`` (kPa, (B, N*s, M*s)).

        ``gains`` (B, strips) default to 1 (a nominal device; N+M strips, plus the diagonal strips
        of layout 'diagonal'); ``noise=True`` needs ``rng``. Returns ``readings`` (B, C) float32 V
        (C = N+M for the orthogonal pair; :mod:`synth.sensors.strips.layouts` for the others),
        ``pressure`` (B, N, M) float32 kPa and ``readings_clean``.
        """
        row, col = self.array.segment_stress(field)
        diag = self.array.diagonal_stress(field) if self.array.diag_ops else None
        b = row.shape[0]
        if gains is None:
            gains = np.ones((b, self.n_strips), dtype=np.float32)
        gains = np.asarray(gains, dtype=np.float32)
        if gains.shape != (b, self.n_strips) or not np.isfinite(gains).all() or (gains <= 0).any():
            raise InputError(
                f"gains: expected positive finite values of shape ({b}, {self.n_strips}), got {gains.shape}"
            )
        clean = self.clean_readings(row, col, gains, diag).astype(np.float32)
        return {
            "readings": self.digitise(clean, rng, noise).astype(np.float32),
            "pressure": self.array.cell_pressure(field).astype(np.float32),
            "readings_clean": clean,
        }

    def load_noise(self) -> np.ndarray:
        """Standard deviation of :meth:`invert_readings` at zero load (B-free, (N+M,)): the readout's
        noise and quantisation step carried through the inverse (local linearisation)."""
        c = self.config.readout
        sd_v = np.sqrt(c.noise_v**2 + c.lsb_v**2 / 12.0)
        step = max(sd_v, 1e-6)
        base = np.full((1, self.n_channels), c.offset_v)
        slope = (self.invert_readings(base + step) - self.invert_readings(base)) / step
        return np.asarray(np.abs(slope[0]) * sd_v)

    def invert_readings(self, readings: np.ndarray) -> np.ndarray:
        """Per-channel load in segment units, ``L = sum over segments of f`` (B, C), assuming unit
        gains (for the orthogonal layout C = N + M: one load per strip).

        For a load on a single segment ``L`` is that segment's ``f``; for a uniform load over ``k``
        segments it is ``k f``. This is the "strip pressure integral" of the classical estimators.
        A two-ended strip's end reads the sum of ``f`` weighted by the share of current that flows
        to that end (:mod:`synth.sensors.strips.layouts`).
        """
        r0 = self.config.piezo.strip_resistance_ohm
        resistance = self.readout.resistance(readings)
        segments = self.layout.segments
        loads = np.clip(1.0 - resistance / r0, 0.0, 1.0) * segments
        if self.layout.linear.any():
            c = self.config.readout
            share = (np.asarray(readings, dtype=np.float64) - c.offset_v) / (c.amplifier_gain * c.supply_v / 4.0)
            loads = np.where(self.layout.linear, np.clip(share, 0.0, None) * segments, loads)
        return loads
