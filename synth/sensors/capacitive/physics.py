"""The capacitive array's physics, stage by stage (seed 001; physics.md section 4).

1. **Cover** (:mod:`~synth.sensors.capacitive.layer`): the surface pressure spreads through the
   elastic cover onto the tabs: load ``F`` (N) on every cell, a linear map of the pressure.
2. **Hysteresis** (:func:`play`): rubber tabs rubbing on their backing and neighbours lag the load.
   A share ``a`` of the load passes through a *relative play* of half-width ``rho`` (Coulomb
   friction grows with the load, so the play's band is a fixed share of it)::

       p_t = clip(p_{t-1}, F_t (1 - rho), F_t (1 + rho)),   p_0 = 0 (a cell at rest)
       u_t = (1 - a) F_t + a p_t                             (the load the tab feels)

   On loading ``u = F (1 - a rho)``, on unloading ``u = F (1 + a rho)``: the branches are
   ``2 a rho`` of the peak apart at the top of a cycle (``Hysteresis.width``, the seed's ~5 %), they
   meet at every turning point (at the peak ``u`` moves with slope ``1 - a`` until the load has
   dropped through the band) and at zero load: every loop closes. The state is carried across the
   frames of a press. Because ``u`` rises strictly with ``F`` on every branch (slope >= ``1 - a``),
   the frame-by-frame inverse is exact (:func:`play_inverse`).
3. **Tab** (:class:`TabLaw`): a tab of height ``h``, area ``A_t`` and modulus ``E`` keeps its volume
   (silicone is incompressible: the seed's reason for tabs), so compressing it by ``x`` widens it to
   ``A_t h / (h - x)``. Integrating ``dF = E A(x) dx / (h - x)`` gives Hooke's law ``F = k x`` for
   small loads (the seed's "fairly linear" dielectric) that stiffens as the tab fills its cell::

       F = F_s x / (h - x)   <=>   h / (h - x) = 1 + F / F_s,   F_s = E A_t

   The tab fills the share ``f = f_0 h / (h - x)`` of the cell's tab layer (``f_0 = A_t / pitch^2``,
   capped at 1 when it touches its neighbours), the rest is air, so the layer's permittivity is
   ``eps_t = 1 + (eps - 1) f``. In series with the solid backing ``d_b``::

       C = eps_0 A_plate / (d_b / eps + (h - x) / eps_t)

   The gap shrinks (``C`` up, convex) while the widening tab raises ``eps_t``: over 0-200 g the
   response is close to linear, as the seed measured. The inverse is closed form (a quadratic in
   ``z = h / (h - x)``). Each cell has its own gain ``g`` (plate area, permittivity) and stiffness
   ``k`` (tab moulding): ``C_ij(F) = g_ij C(F / k_ij)``.
4. **Readout** (:class:`CellResponse`): ``V = V_in C / C_fb`` (the seed's eq. 10, after
   synchronous demodulation); each cell also reads ``crosstalk`` of each 4-neighbour's signal
   (fringe fields between crossings); a common offset drifts during a press (amplifier and
   feedback capacitor temperature); Gaussian noise sets the seed's 7 effective bits over 0-200 g of
   a nominal cell; then the ADC.

Units: mm, N, kPa, pF, V.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from synth.sensors.capacitive.config import CalibrationTable, CapacitiveConfig

__all__ = [
    "EPS0_PF_PER_MM",
    "CellResponse",
    "TabLaw",
    "crosstalk_matrix",
    "device_cells",
    "neighbour_sum",
    "play",
    "play_inverse",
    "play_inverse_step",
]

#: vacuum permittivity in pF/mm
EPS0_PF_PER_MM = 8.8541878128e-3


@dataclass(frozen=True)
class TabLaw:
    """A nominal cell's capacitance against the load its tab feels (module docstring, stage 3)."""

    plate_area_mm2: float
    backing_mm: float
    height_mm: float
    permittivity: float
    fill0: float
    load_scale_n: float

    @classmethod
    def from_config(cls, config: CapacitiveConfig) -> TabLaw:
        d = config.dielectric
        return cls(
            plate_area_mm2=config.geometry.plate_mm**2,
            backing_mm=d.backing_mm,
            height_mm=d.tab_height_mm,
            permittivity=d.permittivity,
            fill0=config.fill_fraction,
            load_scale_n=d.load_scale_n,
        )

    def capacitance_pf(self, load_n: np.ndarray, stiffness: np.ndarray | float = 1.0) -> np.ndarray:
        """``C`` (pF) of cells whose tabs feel ``load_n`` (clamped at 0: a tab is only compressed)."""
        z = 1.0 + np.maximum(load_n, 0.0) / (np.asarray(stiffness) * self.load_scale_n)  # h / (h - x)
        fill = np.minimum(self.fill0 * z, 1.0)
        eps_layer = 1.0 + (self.permittivity - 1.0) * fill
        distance = self.backing_mm / self.permittivity + self.height_mm / (z * eps_layer)
        return np.asarray(EPS0_PF_PER_MM * self.plate_area_mm2 / distance)

    def load_n(self, capacitance_pf: np.ndarray, stiffness: np.ndarray | float = 1.0) -> np.ndarray:
        """Inverse of :meth:`capacitance_pf`. Below the unloaded capacitance (noise) the same formula
        continues smoothly to negative loads, so the noise of an idle cell stays centred on zero."""
        eps = self.permittivity
        distance = EPS0_PF_PER_MM * self.plate_area_mm2 / np.maximum(np.asarray(capacitance_pf, np.float64), 1e-12)
        # the tab layer's share of the series distance; at or below zero the capacitance exceeds a fully
        # compressed tab's (an unbounded load): clamped to a nanometre of effective layer
        layer = np.maximum(distance - self.backing_mm / eps, 1e-6 * self.height_mm)
        ratio = self.height_mm / layer
        c = (eps - 1.0) * self.fill0
        # layer = (h / z) / (1 + c z)  =>  c z^2 + z - ratio = 0, the root written without cancellation
        z_open = 2.0 * ratio / (1.0 + np.sqrt(1.0 + 4.0 * c * ratio))
        # once the tab fills its cell (fill0 z >= 1): layer = h / (z eps); both agree at the cap
        z = np.where(self.fill0 * z_open < 1.0, z_open, ratio / eps)
        return np.asarray((z - 1.0) * np.asarray(stiffness) * self.load_scale_n)


def play(load: np.ndarray, rho: float, share: float) -> np.ndarray:
    """The load each tab feels (module docstring, stage 2) for loads ``(B, F, ...)``: the state runs
    along the frames axis from rest. Negative loads are clamped to 0 (a tab cannot be pulled)."""
    load = np.maximum(np.asarray(load, dtype=np.float64), 0.0)
    state = np.zeros((load.shape[0], *load.shape[2:]))
    out = np.empty_like(load)
    for t in range(load.shape[1]):
        f = load[:, t]
        state = np.clip(state, f * (1.0 - rho), f * (1.0 + rho))
        out[:, t] = (1.0 - share) * f + share * state
    return out


def play_inverse_step(felt: np.ndarray, state: np.ndarray, rho: float, share: float) -> tuple[np.ndarray, np.ndarray]:
    """One frame of :func:`play_inverse`: the applied load of cells feeling ``felt`` whose play is
    at ``state``, and the play's new state (arrays of one shape; a stream carries the state)."""
    u = np.asarray(felt, dtype=np.float64)
    pos = np.maximum(u, 0.0)
    loading = pos / (1.0 - share * rho)
    unloading = pos / (1.0 + share * rho)
    inside = (pos - share * state) / (1.0 - share)
    f = np.where(loading * (1.0 - rho) >= state, loading, np.where(unloading * (1.0 + rho) <= state, unloading, inside))
    return f + np.minimum(u, 0.0), np.clip(state, f * (1.0 - rho), f * (1.0 + rho))


def play_inverse(felt: np.ndarray, rho: float, share: float) -> np.ndarray:
    """The applied loads ``(B, F, ...)`` that :func:`play` turns into ``felt``, frame by frame.

    ``u = (1 - a) F + a clip(p, F (1 - rho), F (1 + rho))`` rises strictly with ``F``, so exactly one
    of its three pieces (loading, unloading, inside the band) holds. A negative ``u`` (an idle
    cell's noise) passes through unchanged and leaves the state alone.
    """
    felt = np.asarray(felt, dtype=np.float64)
    state = np.zeros((felt.shape[0], *felt.shape[2:]))
    out = np.empty_like(felt)
    for t in range(felt.shape[1]):
        out[:, t], state = play_inverse_step(felt[:, t], state, rho, share)
    return out


def neighbour_sum(x: np.ndarray) -> np.ndarray:
    """Sum of every cell's four neighbours over the last two axes (0 beyond the array's edge)."""
    out = np.zeros_like(x)
    out[..., 1:, :] += x[..., :-1, :]
    out[..., :-1, :] += x[..., 1:, :]
    out[..., :, 1:] += x[..., :, :-1]
    out[..., :, :-1] += x[..., :, 1:]
    return out


def crosstalk_matrix(n_rows: int, n_cols: int, crosstalk: float) -> np.ndarray:
    """``I + kappa L`` (row-major cells, ``L`` the 4-neighbour adjacency): own signals -> read signals."""
    eye = np.eye(n_rows * n_cols).reshape(n_rows * n_cols, n_rows, n_cols)
    return np.eye(n_rows * n_cols) + crosstalk * neighbour_sum(eye).reshape(n_rows * n_cols, -1).T


def device_cells(config: CapacitiveConfig) -> tuple[np.ndarray, np.ndarray]:
    """The device's per-cell gain and stiffness ``(N, M)``, drawn from ``device.seed`` (clipped to
    [0.5, 1.5]: a 5-sigma draw cannot make a cell dead or inverted)."""
    d, g = config.device, config.geometry
    rng = np.random.default_rng(np.random.SeedSequence(d.seed, spawn_key=(0xCA9,)))
    shape = (g.n_rows, g.n_cols)
    gain = np.clip(1.0 + d.gain_spread * rng.standard_normal(shape), 0.5, 1.5)
    stiffness = np.clip(1.0 + d.stiffness_spread * rng.standard_normal(shape), 0.5, 1.5)
    return gain, stiffness


@dataclass(frozen=True)
class CellResponse:
    """Cell loads ``(B, F, N, M)`` <-> clean readings (V) of one device (drift excluded): hysteresis,
    tab, crosstalk and ``V = V_in C / C_fb``. Built from a config's true device
    (:meth:`true_device`), its calibration table (:meth:`calibrated`) or the nominal design."""

    law: TabLaw
    gain: np.ndarray
    stiffness: np.ndarray
    crosstalk: float
    rho: float
    share: float
    volts_per_pf: float

    @classmethod
    def true_device(cls, config: CapacitiveConfig) -> CellResponse:
        gain, stiffness = device_cells(config)
        return cls._design(config, gain, stiffness)

    @classmethod
    def nominal(cls, config: CapacitiveConfig) -> CellResponse:
        """Every cell as designed (what an uncalibrated front end assumes)."""
        shape = (config.geometry.n_rows, config.geometry.n_cols)
        return cls._design(config, np.ones(shape), np.ones(shape))

    @classmethod
    def calibrated(cls, config: CapacitiveConfig, table: CalibrationTable) -> CellResponse:
        shape = (config.geometry.n_rows, config.geometry.n_cols)
        return cls._make(
            config,
            np.asarray(table.gain, dtype=np.float64).reshape(shape),
            np.asarray(table.stiffness, dtype=np.float64).reshape(shape),
            table.crosstalk,
            table.play,
            table.play_share,
        )

    @classmethod
    def _design(cls, config: CapacitiveConfig, gain: np.ndarray, stiffness: np.ndarray) -> CellResponse:
        """Given cells with the design's crosstalk and hysteresis."""
        h = config.hysteresis
        return cls._make(config, gain, stiffness, config.readout.crosstalk, h.play, h.play_share)

    @classmethod
    def _make(
        cls,
        config: CapacitiveConfig,
        gain: np.ndarray,
        stiffness: np.ndarray,
        crosstalk: float,
        rho: float,
        share: float,
    ) -> CellResponse:
        r = config.readout
        return cls(TabLaw.from_config(config), gain, stiffness, crosstalk, rho, share, r.drive_v / r.feedback_pf)

    @cached_property
    def _unmix(self) -> np.ndarray:
        n, m = self.gain.shape
        return np.linalg.inv(crosstalk_matrix(n, m, self.crosstalk))

    def volts(self, loads: np.ndarray) -> np.ndarray:
        """Clean readings (V) of cell loads ``(B, F, N, M)`` (N), float64."""
        felt = play(loads, self.rho, self.share)
        own = self.volts_per_pf * self.gain * self.law.capacitance_pf(felt, self.stiffness)
        return own + self.crosstalk * neighbour_sum(own)

    def static_volts(self, felt: np.ndarray) -> np.ndarray:
        """Readings for loads the tabs *feel* (no hysteresis, no crosstalk): one cell's own curve."""
        return self.volts_per_pf * self.gain * self.law.capacitance_pf(felt, self.stiffness)

    def own_volts(self, volts: np.ndarray) -> np.ndarray:
        """Each cell's own signal: the crosstalk undone (a fixed linear map over the cells)."""
        v = np.asarray(volts, dtype=np.float64)
        flat = v.reshape(*v.shape[:-2], -1) @ self._unmix.T
        return flat.reshape(v.shape)

    def felt_loads(self, volts: np.ndarray) -> np.ndarray:
        """The loads the tabs feel (N), from readings ``(..., N, M)``: crosstalk and tab law undone."""
        own = self.own_volts(volts)
        return self.law.load_n(own / (self.volts_per_pf * self.gain), self.stiffness)

    def loads(self, volts: np.ndarray, hysteresis: bool = True) -> np.ndarray:
        """Cell loads ``(B, F, N, M)`` from readings of whole presses (the exact inverse of
        :meth:`volts`); ``hysteresis=False`` reads every frame off the one static curve ``u = F``
        between the two branches (what a calibration without the hysteresis branch fits)."""
        felt = self.felt_loads(volts)
        return play_inverse(felt, self.rho, self.share) if hysteresis else felt
