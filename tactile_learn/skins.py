"""Large strip skins (``strips64``, ``strips128``): reconstruct only around the active strips.

A skin of N x M strips under a few contacts has a few active rows and columns; everything else
reads the sensor at rest. :class:`SkinReconstructor` maps such a frame with a model trained on a
small array (the shipped 16 x 16 ``strips16``, same strip physics) and spends nothing on idle
regions:

1. **Active strips.** Readings -> per-strip loads (segment units, the classical estimators' strip
   pressure integral); a strip is active above ``sigmas`` standard deviations of its load noise at
   rest (the long strip's own noise: a load on one segment moves a 128-segment strip's resistance
   8 times less than a 16-segment strip's). A frame without an active row *and* an active column
   gets the empty map and never reaches the network.
2. **Windows.** Active rows (and columns) are widened by ``margin`` idle strips (less, down to
   none, where that lets them fit one chunk) and merged into groups; groups are packed, in order,
   into chunks of at most the model's 16 strips. With one
   chunk of rows and one of columns (two or three contacts, typically) the chunks form *one*
   virtual 16 x 16 frame: the model sees every active row and column together, so it resolves
   ghosts (which row goes with which column) exactly as on a 16 x 16 array. Otherwise every
   (row chunk, column chunk) pair is a window; a row's load is shared among the column chunks in
   proportion to their loads (and a column's among the row chunks): the max-entropy split of the
   product rule, which keeps each window's row and column totals consistent - across windows, the
   pairing is only what the loads tell.
3. **Virtual readings.** A window's loads (idle strips at exactly zero, the padding strips idle)
   become the readings the 16 x 16 sensor would give for them (its readout law, no noise added),
   all windows of all frames go to the model in one call, and each window's map is written back at
   its strips' crossings; the rest of the map is zero.

    from synth.scene import load_scene
    from tactile_learn.skins import SkinReconstructor
    skin = SkinReconstructor(load_scene("strips128"))        # the shipped strips16 model by default
    maps = skin.predict(readings)                           # (B, 256) V -> (B, 128, 128) kPa
"""

from __future__ import annotations

from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from synth.errors import ConfigError
from synth.scene import Scene
from synth.sensors.strips import StripReadout
from synth.sensors.strips.config import StripsConfig
from tactile_learn.estimators.base import Estimator

__all__ = ["SkinReconstructor", "strip_groups"]


def strip_groups(active: np.ndarray, margin: int) -> list[tuple[int, int]]:
    """``[start, stop)`` intervals of the active strips (1-D bool), each widened by ``margin`` on both
    sides (within the array) and merged where they touch."""
    idx = np.flatnonzero(active)
    if not idx.size:
        return []
    n = len(active)
    # a new group wherever the gap to the previous active strip exceeds two margins
    breaks = np.flatnonzero(np.diff(idx) > 2 * margin + 1)
    starts = np.concatenate([idx[:1], idx[breaks + 1]])
    stops = np.concatenate([idx[breaks], idx[-1:]])
    return [(max(int(a) - margin, 0), min(int(b) + margin + 1, n)) for a, b in zip(starts, stops, strict=True)]


def _chunks(groups: list[tuple[int, int]], size: int) -> list[np.ndarray]:
    """Strip indices of groups packed in order into chunks of at most ``size`` (a longer group is cut)."""
    pieces: list[np.ndarray] = []
    for a, b in groups:
        pieces += [np.arange(s, min(s + size, b)) for s in range(a, b, size)]
    chunks: list[np.ndarray] = []
    current: list[np.ndarray] = []
    for piece in pieces:
        if sum(len(p) for p in current) + len(piece) > size:
            chunks.append(np.concatenate(current))
            current = []
        current.append(piece)
    if current:
        chunks.append(np.concatenate(current))
    return chunks


class _StripLoads:
    """Readings <-> per-strip loads of one array (``StripSensor.invert_readings`` and its inverse,
    without the sensor's mechanics tables, which a large array takes seconds to build)."""

    def __init__(self, config: StripsConfig) -> None:
        g = config.geometry
        self.r0 = config.piezo.strip_resistance_ohm
        self.readout = StripReadout(config.readout, self.r0)
        rows, cols = np.full(g.n_rows, g.n_cols, np.float64), np.full(g.n_cols, g.n_rows, np.float64)
        self.segments = np.concatenate([rows, cols])  # segments per strip: one per crossing
        self.top_v = config.readout.full_scale_v - config.readout.lsb_v  # the highest valid reading
        c = config.readout
        sd_v = float(np.sqrt(c.noise_v**2 + c.lsb_v**2 / 12.0))
        base = np.full((1, len(self.segments)), c.offset_v)
        # load noise at rest: the readout noise carried through the inverse (local linearisation)
        self.noise = np.abs(self.loads(base + sd_v) - self.loads(base))[0]

    def loads(self, readings: np.ndarray) -> np.ndarray:
        resistance = self.readout.resistance(readings)
        return np.clip(1.0 - resistance / self.r0, 0.0, 1.0) * self.segments

    def readings(self, loads: np.ndarray) -> np.ndarray:
        # a load can remove at most all of a strip's resistance: clipped just below (finite volts)
        fraction = np.clip(loads / self.segments, 0.0, 1.0 - 1e-6)
        volts = self.readout.volts(self.r0 * (1.0 - fraction))
        return np.clip(volts, 0.0, self.top_v).astype(np.float32)


class SkinReconstructor(Estimator):
    """Pressure maps of a large strip skin from a small-array model on windows (module docstring)."""

    task = "strips"
    name = "skin"
    kind = "learned"
    backend = "onnxruntime"

    def __init__(
        self,
        scene: Scene,
        window_model: str | Path | Estimator = "strips16",
        sigmas: float = 4.0,
        margin: int = 2,
        threads: int = 1,
    ) -> None:
        self.scene = scene
        self.window_model = window_model
        self.sigmas = sigmas
        self.margin = margin
        self.threads = threads

    @cached_property
    def model_(self) -> Any:
        from tactile_learn.methods import shipped_models
        from tactile_learn.runtime import OnnxEstimator

        if isinstance(self.window_model, Estimator):
            return self.window_model.prepare()
        spec = str(self.window_model)
        path = Path(spec) if spec.endswith(".onnx") else shipped_models("strips").get(spec)
        if path is None:
            raise ConfigError(f"window_model: {spec!r} is not a shipped strip model or an .onnx path")
        return OnnxEstimator(path, threads=self.threads).prepare()

    @cached_property
    def window_scene_(self) -> Scene:
        """The model's own array; its strips must be the skin's (pitch, width, cover, piezoresistance;
        the readouts may differ: windows go through loads, and each array's readout law)."""
        small: Scene = self.model_.scene_
        big = self.scene.sensor
        if not isinstance(big, StripsConfig) or not isinstance(small.sensor, StripsConfig):
            raise ConfigError("a skin and its window model must both be strip arrays")
        same = (
            small.sensor.layers == big.layers
            and small.sensor.piezo == big.piezo
            and small.sensor.geometry.pitch_mm == big.geometry.pitch_mm
            and small.sensor.geometry.strip_width_mm == big.geometry.strip_width_mm
        )
        if not same:
            raise ConfigError(
                f"scene {self.scene.name!r}: its strips differ from those of the window model's scene "
                f"{small.name!r} (pitch, width, cover or piezoresistance): the model does not apply"
            )
        return small

    @cached_property
    def _tables(self) -> tuple[_StripLoads, _StripLoads, np.ndarray, int, int]:
        small = self.window_scene_.sensor.geometry
        big = _StripLoads(self.scene.sensor)
        return big, _StripLoads(self.window_scene_.sensor), self.sigmas * big.noise, small.n_rows, small.n_cols

    def fit(self, X: np.ndarray | None = None, y: Any = None) -> SkinReconstructor:
        self._tables  # noqa: B018 - the model, its scene and the skin's tables, checked now
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        from tactile_learn.tasks import get_task

        return self.predict_checked(get_task("strips").check_inputs(X, self.scene))

    def predict_checked(self, readings: np.ndarray) -> np.ndarray:
        big, small, threshold, n_win, m_win = self._tables
        g = self.scene.sensor.geometry
        n = g.n_rows
        out = np.zeros((len(readings), n, g.n_cols), dtype=np.float32)
        loads = big.loads(readings)
        active = loads > threshold
        loads = np.where(active, loads, 0.0)  # idle strips: exactly at rest, not their noise
        busy = np.flatnonzero(active[:, :n].any(axis=1) & active[:, n:].any(axis=1))
        windows: list[np.ndarray] = []
        places: list[tuple[int, np.ndarray, np.ndarray]] = []
        for b in busy.tolist():
            row_chunks = _packed(active[b, :n], self.margin, n_win)
            col_chunks = _packed(active[b, n:], self.margin, m_win)
            row_loads, col_loads = loads[b, :n], loads[b, n:]
            row_share = _shares([row_loads[c].sum() for c in row_chunks])
            col_share = _shares([col_loads[c].sum() for c in col_chunks])
            for rows, r_share in zip(row_chunks, row_share, strict=True):
                for cols, c_share in zip(col_chunks, col_share, strict=True):
                    window = np.zeros(n_win + m_win)
                    window[: len(rows)] = row_loads[rows] * c_share
                    window[n_win : n_win + len(cols)] = col_loads[cols] * r_share
                    windows.append(window)
                    places.append((b, rows, cols))
        if not windows:
            return out
        maps = self.model_.predict_checked(small.readings(np.stack(windows)))
        for (b, rows, cols), window_map in zip(places, maps, strict=True):
            out[b, rows[:, None], cols[None, :]] = window_map[: len(rows), : len(cols)]
        return out


def _packed(active: np.ndarray, margin: int, size: int) -> list[np.ndarray]:
    """Chunks of the active strips with the widest margin (``margin`` down to 0) that fits them all
    in one chunk of ``size``; if none does, chunks with the full margin."""
    for m in range(margin, -1, -1):
        chunks = _chunks(strip_groups(active, m), size)
        if len(chunks) == 1:
            return chunks
    return _chunks(strip_groups(active, margin), size)


def _shares(totals: list[float]) -> np.ndarray:
    """Each chunk's share of the summed load (1 for a single chunk)."""
    values = np.asarray(totals, dtype=np.float64)
    total = values.sum()
    return values / total if total > 0 else np.full(len(values), 1.0 / len(values))
