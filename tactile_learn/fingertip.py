"""The combined fingertip, frame by frame: the capacitive array says where and how hard the
fingertip is touched, and the thermal classifier runs only on the thermistors under a contact.

Per frame (:meth:`FingertipPipeline.step`):

1. the capacitive front end turns the frame's readings into calibrated cell loads (its hysteresis
   state carried from frame to frame);
2. a capacitive method (classical or learned) gives the force image and the contact mask at the
   fine resolution, and the contact shapes (outline, area, centroid, orientation);
3. a thermistor is *under contact* when the predicted mask covers at least ``coverage`` of its
   footprint; when none is, the thermal classifier is skipped altogether;
4. the thermal classifier (the shipped model, through the thermal task's public interface) reads
   the window of each such thermistor and names its material; every contact pixel above that
   thermistor gets it (``-1``: no contact or not recognised yet). The window ends at the frame's
   time, but never later than ``onset_margin_s`` short of a full window after the contact's onset
   *as the pressure image saw it*: the shipped classifiers were trained on windows that hold the
   onset and some baseline before it (at least 0.2 s), so a long contact is classified on its
   first ``window - margin`` seconds. A thermistor in contact for less than ``min_contact_s`` is
   not classified yet (too early to tell; the thermal evaluation starts at 0.25 s).

``skip=False`` runs the classifier on every thermistor of every frame (then keeps only the contact
pixels): the reference the skipping is timed against. This module is the package's only coupling
to the thermal side of the fingertip: it uses the thermal scene and model as any user would.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from synth.scene import Scene
from synth.sensors.fingertip import FingertipConfig
from tactile_learn.calibration.capacitive import CapacitiveFrontEnd, FrontEndStream
from tactile_learn.estimators.base import Estimator
from tactile_learn.estimators.classical.contact_shapes import ContactShape, contact_shapes

__all__ = ["FingertipFrame", "FingertipPipeline", "FingertipState"]


@dataclass
class FingertipState:
    """What one episode carries from frame to frame: the front end's hysteresis state and the
    thermal sample at which each thermistor's current contact began (-1: not in contact)."""

    front_end: FrontEndStream
    onset: np.ndarray


@dataclass
class FingertipFrame:
    """One frame's output."""

    force_image: np.ndarray  # (H, W) N per fine pixel
    mask: np.ndarray  # (H, W) bool
    material_map: np.ndarray  # (H, W) int16: material index on contact pixels, -1 elsewhere
    thermistor_material: np.ndarray  # (P,) int: -1 not classified (no contact) or classified "none"
    touching: np.ndarray  # (P,) bool: under contact in the pressure image
    classified: np.ndarray  # (P,) bool: the thermal classifier ran on this thermistor
    shapes: list[ContactShape] = field(default_factory=list)
    seconds: float = 0.0


class FingertipPipeline:
    """Streams a fingertip's frames (see the module docstring).

    ``capacitive_method``: a capacitive method name (``bicubic``, ``deconvolution``, a shipped
    model or ``.onnx`` path); ``thermal_method``: a thermal method for the fingertip's thermal
    scene (default the shipped ``thermal_wns``: the seed's wood, nylon and steel).
    """

    def __init__(
        self,
        scene: Scene,
        capacitive_method: str = "deconvolution",
        thermal_method: str = "thermal_wns",
        skip: bool = True,
        coverage: float | None = None,
        shapes: bool = True,
        min_contact_s: float = 0.2,
        onset_margin_s: float = 0.5,
    ) -> None:
        self.scene = scene
        self.capacitive_method = capacitive_method
        self.thermal_method = thermal_method
        self.skip = skip
        self.coverage = coverage
        self.shapes = shapes
        self.min_contact_s = min_contact_s
        self.onset_margin_s = onset_margin_s

    @property
    def config(self) -> FingertipConfig:
        config: FingertipConfig = self.scene.sensor
        return config

    def fit(self, X: Any = None, y: Any = None) -> FingertipPipeline:
        """Build the front end, both methods and the thermistors' footprints."""
        from tactile_learn.methods import resolve_method

        cfg = self.config
        self.capacitive_scene_ = Scene(
            name=f"{self.scene.name}_capacitive", task="capacitive", sensor=cfg.capacitive, outputs=("readings",)
        )
        self.thermal_scene_ = Scene(
            name=f"{self.scene.name}_thermal", task="thermal", sensor=cfg.thermal, outputs=("readings", "latent")
        )
        self.front_end_ = CapacitiveFrontEnd(cfg.capacitive)
        self.capacitive_: Estimator = resolve_method("capacitive", self.capacitive_method, self.capacitive_scene_)
        self.thermal_: Estimator = resolve_method("thermal", self.thermal_method, self.thermal_scene_)
        self.footprints_ = cfg.footprints()
        self.window_ = cfg.thermal.window_samples
        fs = cfg.thermal.readout.sampling_hz
        self.min_samples_ = round(self.min_contact_s * fs)
        self.latest_end_ = max(1, self.window_ - round(self.onset_margin_s * fs))  # samples after onset
        self.none_class_ = len(cfg.thermal.material_list)  # the classifier's last class: touches nothing
        return self

    def start(self) -> FingertipState:
        """A new episode's state: the cells at rest, no thermistor in contact."""
        return FingertipState(self.front_end_.stream(), np.full(len(self.footprints_), -1, dtype=np.int64))

    def step(self, frame: np.ndarray, record: np.ndarray, sample: int, state: FingertipState) -> FingertipFrame:
        """One frame: capacitive ``frame`` (N, M) volts, the thermistors' ``record`` (P, R) so far (or
        whole), ``sample`` the index of the thermal sample at the frame's time."""
        start = time.perf_counter()
        loads = state.front_end.push(frame)
        image = self.capacitive_.predict(loads[None])[0]
        force, mask = image[0], image[1] >= 0.5
        covered = (mask[None] & self.footprints_).sum(axis=(1, 2)) / self.footprints_[0].sum()
        touching = covered >= (self.coverage if self.coverage is not None else self.config.coverage)
        state.onset = np.where(touching, np.where(state.onset < 0, sample, state.onset), -1)
        ready = touching & (sample - state.onset >= self.min_samples_)
        run = ready if self.skip else np.ones_like(touching)
        material = np.full(len(touching), -1, dtype=np.int64)
        if run.any():
            # the window keeps the contact's onset in view (module docstring, 4)
            end = np.where(ready, np.minimum(sample, state.onset + self.latest_end_), sample)[run]
            windows = _windows(record[run], end, self.window_)
            proba = _probabilities(self.thermal_, windows)
            guess = proba.argmax(axis=1)
            material[run] = np.where(guess == self.none_class_, -1, guess)
        material = np.where(ready, material, -1)
        material_map = np.full(mask.shape, -1, dtype=np.int16)
        for j in np.flatnonzero(touching):
            material_map[self.footprints_[j] & mask] = material[j]
        shapes = contact_shapes(force, mask, self.config.capacitive.geometry.h_mm) if self.shapes else []
        return FingertipFrame(
            force_image=force,
            mask=mask,
            material_map=material_map,
            thermistor_material=material,
            touching=touching,
            classified=run,
            shapes=shapes,
            seconds=time.perf_counter() - start,
        )

    def run(self, readings: np.ndarray, record: np.ndarray) -> list[FingertipFrame]:
        """Every frame of one episode: capacitive ``readings`` (F, N, M), thermistor ``record`` (P, R)."""
        cfg = self.config
        fs = cfg.thermal.readout.sampling_hz
        state = self.start()
        samples = np.floor(cfg.frame_times_s[: len(readings)] * fs + 1e-9).astype(int)
        return [self.step(readings[f], record, int(samples[f]), state) for f in range(len(readings))]


def _windows(record: np.ndarray, end: np.ndarray | int, width: int) -> np.ndarray:
    """The ``width`` samples ending at sample ``end`` (inclusive; one per row or one for all) of
    every row, the first repeated before the record starts: what the thermal classifier reads."""
    from tactile_learn.tasks.thermal import windows

    rows = np.asarray(record, dtype=np.float32)
    n = len(rows)
    return windows(rows, np.full(n, rows.shape[1]), np.broadcast_to(np.asarray(end) + 1, (n,)), width)


def _probabilities(estimator: Estimator, x: np.ndarray) -> np.ndarray:
    """Class probabilities of a thermal classifier (``predict_proba``; an estimator without one is
    taken to give them from ``predict``)."""
    proba = getattr(estimator, "predict_proba", None)
    return np.asarray(proba(x) if callable(proba) else estimator.predict(x))
