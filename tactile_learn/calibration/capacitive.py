"""The capacitive array's calibration: each cell's response fitted from presses of known loads, and
the front end that turns readings into calibrated cell loads with it.

**Model** (the simulator's, :mod:`synth.sensors.capacitive.physics`): cell ``c`` of a press reads

    V_c(t) = [(I + kappa L) V_own(t)]_c + delta_b + r_b t,
    V_own,c(t) = (V_in / C_fb) g_c C(u_c(t) / k_c),   u_c = play(F_c; rho, a)

with the design's tab curve ``C`` (geometry and dielectric from the scene), and per cell a gain
``g_c`` and a stiffness ``k_c``; for the array the crosstalk ``kappa`` and the hysteresis (loop width
``2 a rho`` and play share ``a``: the loading and unloading branches); per press a drift offset
``delta_b`` and rate ``r_b`` (nuisances, fitted and dropped). :func:`fit_calibration` finds them by
least squares (``scipy.optimize.least_squares``, trust region, finite differences over the
Jacobian's sparsity: a cell's parameters reach only its own and its neighbours' readings) from
readings whose cell loads ``F`` are known: a rig pressing a probe on every cell through
load-unload cycles (``synth/scenes/capacitive8_rig.toml``; the loads at the tabs come from the
rig's force through the cover's spreading).

**Front end** (:class:`CapacitiveFrontEnd`): readings of whole presses -> cell loads (N): the
common drift removed per frame (from the cells that read least), the crosstalk undone, each cell's
curve inverted, and the hysteresis compensated frame by frame with the play's exact inverse (its
state carried along the press; :meth:`CapacitiveFrontEnd.stream` carries it across calls). Without
a calibration table it assumes the nominal design (every cell alike).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from scipy import optimize, sparse, stats

from synth.errors import DataError
from synth.sensors.capacitive.config import CalibrationTable, CapacitiveConfig
from synth.sensors.capacitive.physics import CellResponse, crosstalk_matrix, neighbour_sum, play_inverse_step
from synth.sensors.capacitive.sensor import CapacitiveModel
from tactile_learn.validation import capacitive_input

__all__ = ["CapacitiveFrontEnd", "FrontEndStream", "fit_calibration"]


def _lower_quarter_bias(n: int) -> float:
    """Expected mean of the lowest quarter of ``n`` standard normal draws (Blom's order statistics)."""
    k = max(1, n // 4)
    ranks = np.arange(1, k + 1)
    return float(np.mean(stats.norm.ppf((ranks - 0.375) / (n + 0.25))))


class CapacitiveFrontEnd:
    """Readings ``(B, F, N, M)`` (V) of whole presses -> calibrated cell loads (N), float32.

    ``calibration``: ``"scene"`` (the config's table; the nominal design if it has none),
    ``"nominal"``, or a :class:`CalibrationTable`. ``hysteresis=False`` reads every frame off one
    static curve (no branch compensation); ``drift=False`` keeps the readout's offset.
    """

    def __init__(
        self,
        config: CapacitiveConfig,
        calibration: str | CalibrationTable = "scene",
        hysteresis: bool = True,
        drift: bool = True,
    ) -> None:
        self.config = config
        self.calibration = calibration
        self.hysteresis = hysteresis
        self.drift = drift

    @cached_property
    def response(self) -> CellResponse:
        table = self.config.calibration if self.calibration == "scene" else self.calibration
        if table is None or table == "nominal":
            return CellResponse.nominal(self.config)
        if not isinstance(table, CalibrationTable):
            raise ValueError(f"calibration: {self.calibration!r} is not 'scene', 'nominal' or a CalibrationTable")
        return CellResponse.calibrated(self.config, table)

    @cached_property
    def _baseline(self) -> tuple[np.ndarray, float]:
        """Every cell's unloaded reading (crosstalk included) and the drift estimate's noise bias."""
        r = self.response
        own = r.static_volts(np.zeros_like(r.gain))
        read = own + r.crosstalk * neighbour_sum(own)
        noise = CapacitiveModel(self.config).noise_v
        return read, noise * _lower_quarter_bias(own.size)

    def offsets(self, readings: np.ndarray) -> np.ndarray:
        """Common drift (V) of every frame ``(..., N, M) -> (...)``: the mean of the quarter of cells
        reading least above their baseline (idle cells, unless contacts cover three quarters of the
        array), less that statistic's expected noise bias."""
        base, bias = self._baseline
        excess = (readings - base).reshape(*readings.shape[:-2], -1)
        k = max(1, excess.shape[-1] // 4)
        low = np.partition(excess, k - 1, axis=-1)[..., :k]
        return np.asarray(low.mean(axis=-1) - bias)

    def felt(self, readings: np.ndarray) -> np.ndarray:
        """The loads the tabs feel (drift removed): the input of the hysteresis stage."""
        volts = np.asarray(readings, dtype=np.float64)
        if self.drift:
            volts = volts - self.offsets(volts)[..., None, None]
        return self.response.felt_loads(volts)

    def loads(self, readings: Any) -> np.ndarray:
        """Calibrated cell loads (N) of whole presses, float32 ``(B, F, N, M)``."""
        volts = capacitive_input(readings, self.config, "readings")
        felt = self.felt(volts)
        if not self.hysteresis:
            return felt.astype(np.float32)
        r = self.response
        state = np.zeros((felt.shape[0], *felt.shape[2:]))
        out = np.empty_like(felt)
        for t in range(felt.shape[1]):
            out[:, t], state = play_inverse_step(felt[:, t], state, r.rho, r.share)
        return out.astype(np.float32)

    def stream(self) -> FrontEndStream:
        """A frame-by-frame front end that carries the hysteresis state across calls."""
        return FrontEndStream(self)


@dataclass
class FrontEndStream:
    """Frames ``(N, M)`` in, cell loads out, one at a time: a press streamed from a sensor."""

    front_end: CapacitiveFrontEnd
    state: np.ndarray | None = None

    def push(self, frame: Any) -> np.ndarray:
        fe = self.front_end
        volts = capacitive_input(np.asarray(frame)[None, None], fe.config, "readings")[0, 0]
        felt = fe.felt(volts[None])[0]
        if not fe.hysteresis:
            return felt.astype(np.float32)
        if self.state is None:
            self.state = np.zeros_like(felt)
        r = fe.response
        loads, self.state = play_inverse_step(felt, self.state, r.rho, r.share)
        return np.asarray(loads, dtype=np.float32)

    def reset(self) -> None:
        """The cells at rest again (a new press)."""
        self.state = None


# ---- fitting -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Layout:
    """Where each parameter sits in the fit's vector."""

    cells: int
    presses: int

    @property
    def size(self) -> int:
        return 2 * self.cells + 3 + 2 * self.presses

    def split(self, x: np.ndarray) -> dict[str, Any]:
        c, b = self.cells, self.presses
        share = 1.0 / (1.0 + np.exp(-x[2 * c + 1]))  # logistic: a in (0, 1)
        return {
            "gain": np.exp(x[:c]),
            "stiffness": np.exp(x[c : 2 * c]),
            "crosstalk": x[2 * c],
            "share": min(share, 0.95),
            "width": np.exp(x[2 * c + 2]),
            "offset": x[2 * c + 3 : 2 * c + 3 + b],
            "rate": x[2 * c + 3 + b :],
        }


def _predict(config: CapacitiveConfig, p: dict[str, Any], loads: np.ndarray) -> np.ndarray:
    shape = (config.geometry.n_rows, config.geometry.n_cols)
    base = CellResponse.nominal(config)
    share = float(p["share"])
    rho = min(float(p["width"]) / (2 * share), 0.99)  # a play wider than the load is unphysical
    response = CellResponse(
        law=base.law,
        gain=p["gain"].reshape(shape),
        stiffness=p["stiffness"].reshape(shape),
        crosstalk=float(p["crosstalk"]),
        rho=rho,
        share=share,
        volts_per_pf=base.volts_per_pf,
    )
    frames = loads.shape[1]
    drift = p["offset"][:, None] + p["rate"][:, None] * np.arange(frames)[None, :]
    return response.volts(loads) + drift[:, :, None, None]


def _sparsity(config: CapacitiveConfig, presses: int, frames: int) -> sparse.csr_matrix:
    """Which readings each parameter can move: a cell's gain and stiffness its own and its four
    neighbours' readings (crosstalk), the array's parameters every reading, a press's drift its own."""
    n, m = config.geometry.n_rows, config.geometry.n_cols
    cells = n * m
    layout = _Layout(cells, presses)
    rows = np.arange(presses * frames * cells).reshape(presses * frames, cells)
    reading, cell = np.nonzero(crosstalk_matrix(n, m, 1.0))  # reading ``reading`` <- cell ``cell``
    parts_r, parts_c = [], []
    for offset in (0, cells):  # gain, then stiffness
        parts_r.append(rows[:, reading].ravel())
        parts_c.append(np.tile(cell + offset, presses * frames))
    for k in range(3):  # crosstalk, play share, loop width
        parts_r.append(rows.ravel())
        parts_c.append(np.full(rows.size, 2 * cells + k))
    press_of_row = np.repeat(np.arange(presses), frames * cells)
    for offset in (2 * cells + 3, 2 * cells + 3 + presses):  # each press's offset, then its rate
        parts_r.append(rows.ravel())
        parts_c.append(press_of_row + offset)
    r, c = np.concatenate(parts_r), np.concatenate(parts_c)
    return sparse.csr_matrix((np.ones(len(r), dtype=bool), (r, c)), shape=(rows.size, layout.size))


def _check_presses(volts: np.ndarray, truth: np.ndarray, config: CapacitiveConfig) -> None:
    """Known loads for every reading, and every cell loaded well into its range by some press."""
    if truth.shape != volts.shape:
        raise DataError(f"cell loads have shape {truth.shape}, readings {volts.shape}: one load per reading")
    if not np.isfinite(truth).all() or (truth < 0).any():
        raise DataError("cell loads must be finite and >= 0 (N)")
    cells = config.n_cells
    peak = truth.reshape(-1, cells).max(axis=0) if truth.size else np.zeros(cells)
    idle = np.flatnonzero(peak < 0.25 * config.readout.full_scale_n)
    if len(idle):
        rows, cols = np.divmod(idle, config.geometry.n_cols)
        names = ", ".join(f"({r}, {c})" for r, c in zip(rows[:6], cols[:6], strict=True))
        more = ", ..." if len(idle) > 6 else ""
        raise DataError(
            f"{len(idle)} cell(s) never loaded to a quarter of the full scale ({names}{more}): "
            "press a probe on every cell through its range (e.g. generate --scene capacitive8_rig)"
        )


def _initial_guess(config: CapacitiveConfig, volts: np.ndarray, layout: _Layout) -> np.ndarray:
    """The nominal device, the design's crosstalk and loop, each press's offset from its first frame."""
    c = layout.cells
    x0 = np.zeros(layout.size)
    x0[2 * c] = config.readout.crosstalk
    x0[2 * c + 1] = 0.0  # logistic(0): a = 0.5
    x0[2 * c + 2] = np.log(max(config.hysteresis.width, 1e-3))
    x0[2 * c + 3 : 2 * c + 3 + layout.presses] = CapacitiveFrontEnd(config, calibration="nominal").offsets(volts[:, 0])
    return x0


def fit_calibration(
    readings: np.ndarray, loads: np.ndarray, config: CapacitiveConfig, max_nfev: int = 200
) -> tuple[CalibrationTable, dict[str, Any]]:
    """A device's :class:`CalibrationTable` from presses of known cell loads.

    ``readings`` (B, F, N, M) volts and ``loads`` (B, F, N, M) newtons at the tabs. Every cell must be
    loaded well into its range by some press (else its curve is not determined). Returns the table
    and a summary (residual against the noise, iterations, the fitted ranges).
    """
    volts = capacitive_input(readings, config, "readings").astype(np.float64)
    truth = np.asarray(loads, dtype=np.float64)
    _check_presses(volts, truth, config)
    presses, frames = volts.shape[:2]
    noise = max(CapacitiveModel(config).noise_v, 1e-6)
    layout = _Layout(config.n_cells, presses)

    def residuals(x: np.ndarray) -> np.ndarray:
        return ((_predict(config, layout.split(x), truth) - volts) / noise).ravel()

    result = optimize.least_squares(
        residuals,
        _initial_guess(config, volts, layout),
        jac_sparsity=_sparsity(config, presses, frames),
        x_scale="jac",
        max_nfev=max_nfev,
        method="trf",
        tr_solver="lsmr",
    )
    p = layout.split(result.x)
    table = CalibrationTable(
        gain=tuple(round(float(v), 6) for v in p["gain"]),
        stiffness=tuple(round(float(v), 6) for v in p["stiffness"]),
        crosstalk=round(float(min(max(p["crosstalk"], 0.0), 0.5)), 6),
        hysteresis_width=round(float(min(p["width"], 0.5)), 6),
        play_share=round(float(p["share"]), 6),
        presses=int(presses),
        rms_residual_v=round(float(np.sqrt(np.mean(result.fun**2))) * noise, 9),
    )
    summary = {
        "presses": int(presses),
        "frames": int(frames),
        "rms_residual_v": table.rms_residual_v,
        "noise_v": noise,
        "iterations": int(result.nfev),
        "converged": bool(result.success),
        "crosstalk": table.crosstalk,
        "hysteresis_width": table.hysteresis_width,
        "play_share": table.play_share,
        "gain_range": [float(p["gain"].min()), float(p["gain"].max())],
        "stiffness_range": [float(p["stiffness"].min()), float(p["stiffness"].max())],
    }
    return table, summary
