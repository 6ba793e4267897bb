"""Soft strip array: orthogonal conductive-rubber strips, one reading per strip (other layouts:
diagonal strips, two-ended readout, taps - :mod:`synth.sensors.strips.layouts`).

Physics, from stimulus to reading (every stage is its own object, so tests can check each):

1. **Surface pressure** (kPa) on a fine lattice of ``s = samples_per_pitch`` cells per pitch,
   ``(N s, M s)`` cells of pitch ``h = pitch / s``; cell ``(k, l)`` is centred at
   ``y = (k + 0.5) h``, ``x = (l + 0.5) h`` (``synth.stimuli``).
2. **Stress at depth** (:class:`StripArray`): Boussinesq's exact rectangle kernel at the row
   strips' depth (``cover_mm``) and the column strips' depth (``cover_mm + strip_thickness_mm``),
   averaged over each strip *segment* - the ``pitch``-long piece of a strip at one crossing, across
   the strip's width (``synth.mechanics``).
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
from synth.mechanics import patch_operator, separable_kernel
from synth.sensors.strips.config import StripReadout as ReadoutConfig
from synth.sensors.strips.config import StripsConfig
from synth.sensors.strips.layouts import StripLayout
from synth.stimuli import Windows

__all__ = [
    "Adc",
    "GaussianNoise",
    "PiezoLaw",
    "StripArray",
    "StripReadout",
    "StripSensor",
]


def _band_weights(n: int, cells: int, h: float, pitch: float, width: float) -> np.ndarray:
    """(n, cells): share of each lattice cell inside strip ``i``'s band, normalised to average."""
    lo = np.arange(n) * pitch + (pitch - width) / 2
    edges = np.arange(cells + 1) * h
    overlap = np.clip(
        np.minimum(edges[1:][None, :], (lo + width)[:, None]) - np.maximum(edges[:-1][None, :], lo[:, None]),
        0,
        None,
    )
    return overlap / width


def _segment_weights(n: int, per: int) -> np.ndarray:
    """(n, n*per): average over the ``per`` lattice cells of each pitch-long segment."""
    return np.kron(np.eye(n), np.full((1, per), 1.0 / per))


class StripArray:
    """Geometry and mechanics: surface pressure -> mean stress on every strip segment.

    Pressure may sit on a padded lattice reaching ``pad`` cells beyond the array on every side
    (contacts near or past the border load the strips through the cover too).
    """

    def __init__(self, config: StripsConfig, pad: int = 0) -> None:
        g, layers = config.geometry, config.layers
        self.config = config
        self.n_rows, self.n_cols, self.s = g.n_rows, g.n_cols, g.samples_per_pitch
        self.h = g.pitch_mm / g.samples_per_pitch
        self.field_shape = (g.n_rows * self.s, g.n_cols * self.s)
        self.pad = pad
        ny, nx = self.field_shape
        pos_y = np.arange(-pad, ny + pad)
        pos_x = np.arange(-pad, nx + pad)
        half = max(ny, nx) + pad
        row_band = _band_weights(g.n_rows, ny, self.h, g.pitch_mm, g.strip_width_mm)
        col_band = _band_weights(g.n_cols, nx, self.h, g.pitch_mm, g.strip_width_mm)
        seg_x = _segment_weights(g.n_cols, self.s)
        seg_y = _segment_weights(g.n_rows, self.s)
        self.depth_row_mm = layers.cover_mm
        self.depth_col_mm = layers.cover_mm + layers.strip_thickness_mm
        k_row = separable_kernel(self.h, self.depth_row_mm, half, layers.kernel_rank_tol)
        k_col = separable_kernel(self.h, self.depth_col_mm, half, layers.kernel_rank_tol)
        self.kernel_rel_error = max(k_row.rel_error, k_col.rel_error)
        f32 = np.float32
        # row layer: average across row i's band (y) and along segment j (x)
        self.row_y = np.stack([patch_operator(row_band, r, pos_y, half) for r in k_row.rows]).astype(f32)
        self.row_x = np.stack([patch_operator(seg_x, c, pos_x, half) for c in k_row.cols]).astype(f32)
        # column layer: along segment i (y) and across column j's band (x)
        self.col_y = np.stack([patch_operator(seg_y, r, pos_y, half) for r in k_col.rows]).astype(f32)
        self.col_x = np.stack([patch_operator(col_band, c, pos_x, half) for c in k_col.cols]).astype(f32)
        # diagonal layers (layout 'diagonal'), each one strip thickness below the one above it: a
        # diagonal segment sees the mean stress over its whole cell at its depth (synth.sensors.strips.layouts)
        self.layout = StripLayout(g)
        self.depth_diag_mm = [
            layers.cover_mm + (k + 2) * layers.strip_thickness_mm for k in range(len(self.layout.layers) - 2)
        ]
        self.diag_ops: list[tuple[np.ndarray, np.ndarray]] = []
        for depth in self.depth_diag_mm:
            k_diag = separable_kernel(self.h, depth, half, layers.kernel_rank_tol)
            self.kernel_rel_error = max(self.kernel_rel_error, k_diag.rel_error)
            self.diag_ops.append(
                (
                    np.stack([patch_operator(seg_y, r, pos_y, half) for r in k_diag.rows]).astype(f32),
                    np.stack([patch_operator(seg_x, c, pos_x, half) for c in k_diag.cols]).astype(f32),
                )
            )
        self._diag_cache: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
        # ground truth: mean surface pressure over each pitch cell (zero weight outside the array)
        self.cell_y = np.zeros((g.n_rows, len(pos_y)), dtype=f32)
        self.cell_y[:, pad : pad + ny] = seg_y
        self.cell_x = np.zeros((g.n_cols, len(pos_x)), dtype=f32)
        self.cell_x[:, pad : pad + nx] = seg_x
        self._table_cache: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}

    # -- full-field path (user fields) ------------------------------------------------------------

    def _check_field(self, field: np.ndarray) -> np.ndarray:
        arr = np.asarray(field)
        if arr.ndim != 3 or arr.shape[1:] != self.field_shape:
            raise InputError(
                f"pressure field: expected shape (B, {self.field_shape[0]}, {self.field_shape[1]}), got {arr.shape}"
            )
        if not np.isfinite(arr).all():
            raise InputError("pressure field: contains NaN or inf")
        if (arr < 0).any():
            raise InputError("pressure field: negative pressure (kPa) is not a contact (the layer cannot pull)")
        return np.ascontiguousarray(arr, dtype=np.float32)

    def _inner(self, op: np.ndarray) -> np.ndarray:
        ny = op.shape[-1] - 2 * self.pad
        return op[..., self.pad : self.pad + ny]

    def segment_stress(self, field: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean stress (kPa) on every row segment and column segment, each ``(B, N, M)``, for surface
        pressure ``field`` (B, N*s, M*s) on the array's own lattice."""
        p = self._check_field(field)
        ry, rx = self._inner(self.row_y), self._inner(self.row_x)
        cy, cx = self._inner(self.col_y), self._inner(self.col_x)
        row = sum((ry[r] @ p @ rx[r].T for r in range(len(ry))), np.zeros(1, np.float32))
        col = sum((cy[r] @ p @ cx[r].T for r in range(len(cy))), np.zeros(1, np.float32))
        # the separable kernel's truncation can leave -1e-6-sized negatives far from any load
        return np.maximum(row, 0.0), np.maximum(col, 0.0)

    def diagonal_stress(self, field: np.ndarray) -> np.ndarray:
        """Mean stress (kPa) over every cell at each diagonal layer's depth, (B, D, N, M) (D = 0 for
        layouts without diagonal strips)."""
        p = self._check_field(field)
        out = np.zeros((len(p), len(self.diag_ops), self.n_rows, self.n_cols), np.float32)
        for k, (dy, dx) in enumerate(self.diag_ops):
            dy, dx = self._inner(dy), self._inner(dx)
            out[:, k] = sum((dy[r] @ p @ dx[r].T for r in range(len(dy))), np.zeros(1, np.float32))
        return np.maximum(out, 0.0)

    def cell_pressure(self, field: np.ndarray) -> np.ndarray:
        """Intersection map (B, N, M): mean surface pressure over each pitch cell."""
        p = self._check_field(field)
        return self._inner(self.cell_y) @ p @ self._inner(self.cell_x).T

    def cell_stress_operators(self) -> tuple[np.ndarray, np.ndarray]:
        """Dense ``(N*M, N*M)`` float64 matrices mapping a map of cell-constant surface pressure
        (flattened row-major) to the mean stress on every row segment and column segment."""
        up_y = np.kron(np.eye(self.n_rows), np.ones((self.s, 1)))  # lattice rows of each cell
        up_x = np.kron(np.eye(self.n_cols), np.ones((self.s, 1)))

        def dense(ops_y: np.ndarray, ops_x: np.ndarray) -> np.ndarray:
            ay = self._inner(ops_y).astype(np.float64) @ up_y  # (R, N, N)
            bx = self._inner(ops_x).astype(np.float64) @ up_x  # (R, M, M)
            # row-major vec(A X B^T) = (A kron B) vec(X)
            return np.einsum("rik,rjl->ijkl", ay, bx).reshape(self.n_rows * self.n_cols, -1)

        return dense(self.row_y, self.row_x), dense(self.col_y, self.col_x)

    def layer_cell_operators(self) -> list[np.ndarray]:
        """:meth:`cell_stress_operators` for every layer of the layout, diagonal layers last."""
        up_y = np.kron(np.eye(self.n_rows), np.ones((self.s, 1)))
        up_x = np.kron(np.eye(self.n_cols), np.ones((self.s, 1)))
        ops = list(self.cell_stress_operators())
        for dy, dx in self.diag_ops:
            ay = self._inner(dy).astype(np.float64) @ up_y
            bx = self._inner(dx).astype(np.float64) @ up_x
            ops.append(np.einsum("rik,rjl->ijkl", ay, bx).reshape(self.n_rows * self.n_cols, -1))
        return ops

    # -- windowed path (simulated contacts: work only where there is load) ---------------------

    def _tables(self, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Operators cut into every ``size``-long run of padded positions, cached per window size.

        Returns the y-table (positions, R_row + R_col + 1, N, size) holding row-layer, column-layer and
        cell-mean operators, and the x-tables (positions, R*size, M) of each layer and the cells.
        """
        cached = self._table_cache.get(size)
        if cached is None:

            def slide_y(op: np.ndarray) -> np.ndarray:
                view = np.lib.stride_tricks.sliding_window_view(op, size, axis=-1)  # (R, n, pos, size)
                return np.ascontiguousarray(view.transpose(2, 0, 1, 3))

            def slide_x(op: np.ndarray) -> np.ndarray:
                view = slide_y(op)  # (pos, R, n, size)
                pos, rank, n, _ = view.shape
                return np.ascontiguousarray(view.transpose(0, 1, 3, 2)).reshape(pos, rank * size, n)

            y = slide_y(np.concatenate([self.row_y, self.col_y, self.cell_y[None]], axis=0))
            cached = (y, slide_x(self.row_x), slide_x(self.col_x), slide_x(self.cell_x[None]))
            self._table_cache[size] = cached
        return cached

    def window_products(self, windows: Windows, stress: bool = True, cells: bool = True) -> dict[str, np.ndarray]:
        """Per-window contributions (c, N, M): ``row``/``col`` segment stress and ``cells`` means.

        Two batched matrix products per window instead of a convolution of the whole lattice.
        """
        size = windows.values.shape[-1]
        ty, trow, tcol, tcell = self._tables(size)
        iy = windows.y0 + self.pad
        ix = windows.x0 + self.pad
        if (iy < 0).any() or (iy >= len(ty)).any() or (ix < 0).any() or (ix >= len(trow)).any():
            raise ValueError("a contact window reaches beyond the padded lattice (pad too small)")
        c = len(iy)
        # the row and column layers lie at different depths: their kernels may need different ranks
        r_row, r_col = self.row_y.shape[0], self.col_y.shape[0]
        n = self.n_rows
        vals = windows.values.astype(np.float32)
        gy = ty[iy]  # (c, R_row + R_col + 1, N, size)
        first = (gy.reshape(c, -1, size) @ vals).reshape(c, r_row + r_col + 1, n, size)
        out: dict[str, np.ndarray] = {}

        def finish(part: np.ndarray, table: np.ndarray) -> np.ndarray:
            flat = np.ascontiguousarray(part.transpose(0, 2, 1, 3)).reshape(c, n, -1)
            return flat @ table[ix]

        if stress:
            out["row"] = finish(first[:, :r_row], trow)
            out["col"] = finish(first[:, r_row : r_row + r_col], tcol)
        if cells:
            out["cells"] = finish(first[:, r_row + r_col :], tcell)
        if stress and self.diag_ops:
            # separate products: the orthogonal layers' tables (and their float32 sums) stay as they were
            parts = []
            for dy, dx in self._diag_tables(size):
                rank = dy.shape[1]
                part = (dy[iy].reshape(c, -1, size) @ vals).reshape(c, rank, n, size)
                parts.append(finish(part, dx))
            out["diag"] = np.stack(parts, axis=1)
        return out

    def _diag_tables(self, size: int) -> list[tuple[np.ndarray, np.ndarray]]:
        cached = self._diag_cache.get(size)
        if cached is None:
            cached = []
            for dy, dx in self.diag_ops:
                y = np.ascontiguousarray(
                    np.lib.stride_tricks.sliding_window_view(dy, size, axis=-1).transpose(2, 0, 1, 3)
                )
                view = np.lib.stride_tricks.sliding_window_view(dx, size, axis=-1).transpose(2, 0, 1, 3)
                pos, rank, m, _ = view.shape
                x = np.ascontiguousarray(view.transpose(0, 1, 3, 2)).reshape(pos, rank * size, m)
                cached.append((y, x))
            self._diag_cache[size] = cached
        return cached


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
