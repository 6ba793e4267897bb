"""The seed's combined fingertip (seed 001): the 8 x 8 capacitive array over the 4 x 4 heated
thermistor array, both under one surface. One sample is a touch *episode*: the thermal record of
every thermistor and the capacitive frames over the same time.

Composition (the thermal physics stays the thermal simulator's, used through its public API):

1. The thermal simulator draws a touch of one or two objects (``[fingertip.thermal]``; with
   ``objects.second_object = 1`` every touch has two): every pixel's record, material, onset and
   release.
2. The capacitive array is pressed by one or two contacts from its shape library
   (``[fingertip.capacitive.stimuli]``); contact ``k`` is object ``k`` of the touch: it presses from
   that object's onset (the load ramping up over ``ramp_s``) to its release (ramping down before
   it), at ``frame_hz`` frames per second over the thermal record.
3. Thermistor ``j`` (under ``rows/R x cols/C`` capacitive cells) touches the contact covering at
   least ``coverage`` of its footprint at the contact's peak; its record is that object's pixel
   curve (its own when the thermal touch put it on that object, else another pixel of the object:
   pixels are independent in the thermal model); a thermistor under no contact takes an untouched
   pixel's curve of the same touch, or (when the touch left none) the steady state the thermal
   model documents, ``T_amb + Q / G``, through the thermal readout's noise and ADC.

Truth: ``thermistor_material`` (-1 none) and ``thermistor_contact`` per frame (under a contact that
presses in that frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from synth.config import param
from synth.errors import ConfigError
from synth.scene import Scene
from synth.sensors import sensor_module
from synth.sensors.base import ArraySpec
from synth.sensors.capacitive import CapacitiveConfig, CapacitiveModel, PressGenerator
from synth.sensors.thermal import Readout as ThermalReadout
from synth.sensors.thermal import ThermalConfig

__all__ = [
    "CONFIG_CLASS",
    "DEFAULT_OUTPUTS",
    "OUTPUTS",
    "FingertipConfig",
    "FingertipSimulator",
    "make_simulator",
    "press_profile",
]


@dataclass(frozen=True)
class FingertipConfig:
    """Both arrays share the fingertip's surface: the thermistor grid divides the capacitive one."""

    frame_hz: float = param(10.0, lo=0.1, hi=1000.0, unit="Hz", doc="capacitive frame rate")
    ramp_s: float = param(0.3, lo=0.0, hi=10.0, unit="s", doc="load ramp at onset and before release")
    coverage: float = param(0.25, lo=0.0, lo_open=True, hi=1.0, doc="footprint share a contact must cover")
    capacitive: CapacitiveConfig = param(CapacitiveConfig())
    thermal: ThermalConfig = param(ThermalConfig())

    def __post_init__(self) -> None:
        g, (rows, cols) = self.capacitive.geometry, self.thermal.grid
        if g.n_rows % rows or g.n_cols % cols:
            raise ConfigError(
                f"thermal.grid: {rows} x {cols} thermistors do not tile the {g.n_rows} x {g.n_cols} capacitive cells"
            )

    @property
    def frames(self) -> int:
        return max(1, math.floor(self.thermal.readout.duration_s * self.frame_hz + 1e-9))

    @property
    def frame_times_s(self) -> np.ndarray:
        return np.arange(self.frames) / self.frame_hz

    def footprints(self) -> np.ndarray:
        """``(P, H, W)`` bool: every thermistor's footprint on the capacitive fine lattice."""
        rows, cols = self.thermal.grid
        ny, nx = self.capacitive.geometry.image_shape
        fy, fx = ny // rows, nx // cols
        out = np.zeros((rows * cols, ny, nx), dtype=bool)
        for j in range(rows * cols):
            r, c = divmod(j, cols)
            out[j, r * fy : (r + 1) * fy, c * fx : (c + 1) * fx] = True
        return out


CONFIG_CLASS = FingertipConfig
OUTPUTS: dict[str, str] = {
    "readings": "capacitive readings (V) of every frame (F, N, M) and thermistor records thermal_readings (P, R)",
    "cell_load": "true load on every tab (N): (F, N, M)",
    "image": "surface force (N) and true contact mask on the fine lattice: (F, N s, M s)",
    "latent": "per thermistor: material (-1 none), contact per frame; contact list of the episode",
}
DEFAULT_OUTPUTS = ("readings", "latent")


#: episodes rasterised at once (bounds the memory of a 1024-episode chunk)
_EPISODES_PER_BATCH = 64


def press_profile(times: np.ndarray, onset: np.ndarray, release: np.ndarray, ramp_s: float) -> np.ndarray:
    """Load fraction ``(B, F, K)`` at ``times`` (F,) for contacts pressing from ``onset`` to
    ``release`` (B, K): up over ``ramp_s`` after onset, down over ``ramp_s`` before release."""
    t = times[None, :, None]
    ramp = max(ramp_s, 1e-9)  # a zero ramp: a step
    up = np.clip((t - onset[:, None, :]) / ramp, 0.0, 1.0)
    down = np.clip((release[:, None, :] - t) / ramp, 0.0, 1.0)
    return np.where((t >= onset[:, None, :]) & (t < release[:, None, :]), np.minimum(up, down), 0.0)


class FingertipSimulator:
    """Draws touch episodes (module docstring); only the scene's wanted outputs are returned."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.config: FingertipConfig = scene.sensor
        cap = self.config.capacitive
        self.frames = self.config.frames
        self.cap_model = CapacitiveModel(cap, frames=self.frames)
        self.cap_stimuli = PressGenerator(cap, self.cap_model)
        self.thermal_scene = Scene(
            name=f"{scene.name}_thermal",
            task="thermal",
            sensor=self.config.thermal,
            outputs=("readings", "latent"),
            noise=scene.noise,
        )

    @cached_property
    def thermal(self) -> object:
        return sensor_module("thermal").make_simulator(self.thermal_scene)

    def output_specs(self) -> dict[str, ArraySpec]:
        g = self.config.capacitive.geometry
        f, p = self.frames, self.config.thermal.n_pixels
        k = self.config.capacitive.stimuli.count[1]
        specs: dict[str, ArraySpec] = {}
        if self.scene.wants("readings"):
            specs["readings"] = ArraySpec((f, g.n_rows, g.n_cols), "float32", "capacitive readings (V) of every frame")
            specs["thermal_readings"] = ArraySpec(
                (p, self.config.thermal.readout.n_samples), "float32", "thermistor temperatures (degC), row-major"
            )
        if self.scene.wants("cell_load"):
            specs["cell_load"] = ArraySpec((f, g.n_rows, g.n_cols), "float32", "true load on every tab (N)")
        if self.scene.wants("image"):
            specs["force_image"] = ArraySpec((f, *g.image_shape), "float32", "surface force per fine cell (N)")
            specs["contact_mask"] = ArraySpec((f, *g.image_shape), "bool", "true contact mask")
        if self.scene.wants("latent"):
            specs.update(
                thermistor_material=ArraySpec((p,), "int16", "material index into the thermal scene's list, -1 none"),
                thermistor_contact=ArraySpec((f, p), "bool", "thermistor under a pressing contact, per frame"),
                latent_kind=ArraySpec((k,), "int8", "contact kind index into synth.stimuli.KINDS, -1 = none"),
                latent_xy_mm=ArraySpec((k, 2), "float32", "contact centre (x, y) in mm"),
                latent_onset_s=ArraySpec((k,), "float32", "contact onset (s)"),
                latent_release_s=ArraySpec((k,), "float32", "contact release (s)"),
                latent_force_n=ArraySpec((k,), "float32", "contact peak force (N)"),
            )
        return specs

    def simulate(self, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        th = self.thermal.simulate(n, rng)  # type: ignore[attr-defined]
        contacts = self.cap_stimuli.draw_contacts(n, rng)
        drift = self.cap_stimuli.draw_drift(n, self.frames, rng)
        parts = []
        # an episode's frames on the fine lattice take ~0.5 MB: rasterised 64 episodes at a time
        for lo in range(0, n, _EPISODES_PER_BATCH):
            sel = slice(lo, min(n, lo + _EPISODES_PER_BATCH))
            part = {k: v[sel] for k, v in th.items()}
            parts.append(self._episodes(part, {k: v[sel] for k, v in contacts.items()}, drift[sel], rng))
        if not parts:
            return {k: np.zeros((0, *s.shape), dtype=s.dtype) for k, s in self.output_specs().items()}
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}

    def _episodes(
        self,
        th: dict[str, np.ndarray],
        contacts: dict[str, np.ndarray],
        drift: np.ndarray,
        rng: np.random.Generator,
    ) -> dict[str, np.ndarray]:
        cfg = self.config
        k = contacts["present"].shape[1]
        obj = np.asarray(th["latent_object"]).astype(np.int64)  # (n, P)
        objects = int(obj.max(initial=0)) + 1
        # contact k is object k of the touch (the last object if the touch has fewer)
        which = np.minimum(np.arange(k), objects - 1)
        onset = np.stack([_object_mean(th["latent_onset_s"], obj, w) for w in which], axis=1)
        release = np.stack([_object_mean(th["latent_release_s"], obj, w) for w in which], axis=1)
        load = press_profile(cfg.frame_times_s, onset, release, cfg.ramp_s)
        stimulus = self.cap_stimuli.press(contacts, load, drift)
        assigned = self._assign(contacts)  # (n, P): contact index or -1
        record, material = self._records(th, obj, assigned, which, rng)
        out: dict[str, np.ndarray] = {}
        if self.scene.wants("readings"):
            out["readings"] = self.cap_model.forward(stimulus, rng if self.scene.noise else None).astype(np.float32)
            out["thermal_readings"] = record.astype(np.float32)
        if self.scene.wants("cell_load"):
            out["cell_load"] = self.cap_model.physics(stimulus).astype(np.float32)
        if self.scene.wants("image"):
            truth = self.cap_stimuli.truth(stimulus, ("image",))
            out["force_image"], out["contact_mask"] = truth["force_image"], truth["contact_mask"]
        if self.scene.wants("latent"):
            pressing = np.take_along_axis(load, np.maximum(assigned, 0)[:, None, :], axis=2) > 0  # (n, F, P)
            out.update(
                thermistor_material=material.astype(np.int16),
                thermistor_contact=pressing & (assigned >= 0)[:, None, :],
                latent_kind=contacts["kind"].astype(np.int8),
                latent_xy_mm=np.stack([contacts["x_mm"], contacts["y_mm"]], -1).astype(np.float32),
                latent_onset_s=onset.astype(np.float32),
                latent_release_s=release.astype(np.float32),
                latent_force_n=np.where(contacts["present"], contacts["force_n"], 0.0).astype(np.float32),
            )
        return out

    def _assign(self, contacts: dict[str, np.ndarray]) -> np.ndarray:
        """Contact touching every thermistor at its peak (the one covering most of it), -1 none."""
        n, k = contacts["present"].shape
        foot = self.config.footprints()  # (P, H, W)
        cover = np.zeros((n, k, len(foot)))
        for slot in range(k):
            alone = np.zeros((n, 1, k))
            alone[:, 0, slot] = 1.0
            mask = self.cap_stimuli.press(contacts, alone, np.zeros((n, 1))).mask
            assert mask is not None  # generated presses carry their mask
            cover[:, slot] = np.einsum("bhw,phw->bp", mask[:, 0].astype(np.float64), foot) / foot[0].sum()
        best = cover.argmax(axis=1)
        return np.where(np.take_along_axis(cover, best[:, None, :], axis=1)[:, 0] >= self.config.coverage, best, -1)

    def _records(
        self,
        th: dict[str, np.ndarray],
        obj: np.ndarray,
        assigned: np.ndarray,
        which: np.ndarray,
        rng: np.random.Generator,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Every thermistor's record and material from the touch's pixels (module docstring, 3)."""
        readings = np.asarray(th["readings"], dtype=np.float64)
        material = np.asarray(th["latent_material"]).astype(np.int64)
        n, p, _ = readings.shape
        wanted = np.where(assigned >= 0, which[np.maximum(assigned, 0)], -1)  # object each thermistor shows
        record = np.empty_like(readings)
        out_material = np.full((n, p), -1, dtype=np.int64)
        steady = np.asarray(th["latent_ambient_c"]) + np.asarray(th["latent_heater_w_m2"]) / np.asarray(
            th["latent_loss_w_m2k"]
        )
        readout = ThermalReadout(self.config.thermal.readout)
        for b in range(n):
            for j in range(p):
                target = wanted[b, j]
                if obj[b, j] == target:
                    source = j
                else:
                    candidates = np.flatnonzero(obj[b] == target)
                    source = int(candidates[0]) if len(candidates) else -1
                if source >= 0:
                    record[b, j] = readings[b, source]
                    out_material[b, j] = material[b, source]
                else:  # no untouched pixel in this touch: the documented steady state through the readout
                    clean = np.full(readings.shape[2], steady[b, j])
                    record[b, j] = readout(clean, rng, self.scene.noise)
        return record, out_material


def _object_mean(values: np.ndarray, obj: np.ndarray, which: int) -> np.ndarray:
    """Mean of ``values`` (n, P) over each touch's pixels of object ``which`` (n,)."""
    sel = obj == which
    v = np.asarray(values, dtype=np.float64)
    fallback = v.mean(axis=1)  # a touch without that object: the touch's own timing
    return np.where(sel.any(axis=1), (v * sel).sum(axis=1) / np.maximum(sel.sum(axis=1), 1), fallback)


def make_simulator(scene: Scene) -> FingertipSimulator:
    return FingertipSimulator(scene)
