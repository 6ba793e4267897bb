"""Presses on the FSR film and the films they are pressed on (see :mod:`synth.sensors.fsr`).

A :class:`FsrPresses` stimulus is a batch of frames of one round press each (or none): centre,
force, tip radius; the gains of the film each frame is pressed on and of that press (with the
datasheet's repeatability); for drawn frames the film id, the unusual presses of scenes that
have them (a second press, a flat indenter) and the ADC's unit noise draws. A user's contacts
become a stimulus with :meth:`FsrPresses.from_contacts`.

:class:`PressGenerator` draws frames in the random stream of the simulator it replaces (contacts,
films, repeatability, ADC noise, then the unusual presses), so datasets keep their bytes: the ADC
noise is drawn with the stimulus whether noise is on or not, and the model's noise stage uses
those draws (``FsrModel.forward``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from synth.errors import InputError
from synth.sensors.arrays import optional, take
from synth.sensors.base import ArraySpec
from synth.sensors.fsr.config import N_SENSORS, FilmConfig, FsrConfig
from synth.sensors.fsr.geometry import TRIANGLES, triangle_vertices
from synth.sensors.model import SensorModel, StimulusGenerator

__all__ = ["FsrPresses", "PressGenerator", "film_gains"]


def film_gains(film_id: int, film: FilmConfig) -> np.ndarray:
    """The six part gains of film ``film_id`` (a pure function of the id), float64."""
    if film.gains is not None:
        return np.asarray(film.gains, dtype=np.float64)
    rng = np.random.default_rng([int(film_id), 0x46535236])
    return 1.0 + film.gain_spread * _unit_draw(rng, N_SENSORS, film.distribution)


def _unit_draw(rng: np.random.Generator, shape: int | tuple[int, ...], distribution: str) -> np.ndarray:
    """Zero-mean draws scaled so that the datasheet's +/- figure is 1: U(-1, 1) or N(0, 1) cut at 3."""
    if distribution == "uniform":
        return rng.uniform(-1.0, 1.0, size=shape)
    return np.clip(rng.standard_normal(shape), -3.0, 3.0)


@dataclass(frozen=True)
class FsrPresses:
    """``xy_mm`` (B, 2) centre (mm, film centre origin), ``force_n`` (B,) (0: no contact),
    ``tip_radius_mm`` (B,), ``press_gain`` (B, 6) the six parts' gains of every press, float64;
    for drawn frames ``film_id`` (B,), ``film_gain`` (B, 6), ``adc_noise`` (B, 6) unit normal draws
    and ``unusual`` (second presses and flat indenters: ``FsrConfig.stimulus.unusual`` scenes)."""

    xy_mm: np.ndarray
    force_n: np.ndarray
    tip_radius_mm: np.ndarray
    press_gain: np.ndarray
    film_id: np.ndarray | None = None
    film_gain: np.ndarray | None = None
    adc_noise: np.ndarray | None = None
    unusual: dict[str, np.ndarray] | None = None

    #: the arrays of :meth:`from_arrays` (a user's ``.npz``)
    FIELDS: ClassVar[dict[str, str]] = {
        "xy_mm": "(B, 2) press centre in mm, origin at the film's centre, x right, y up",
        "force_n": "(B,) applied force in N (0: no contact)",
        "tip_radius_mm": "(B,) or one value: the spherical tip's radius in mm",
        "press_gain": "(B, 6), (6,) or one value: the six parts' gains, optional (alias 'gains'; default 1)",
    }

    def __len__(self) -> int:
        return len(self.force_n)

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> FsrPresses:
        """A stimulus from named arrays (:attr:`FIELDS`), validated."""
        gains = optional(arrays, "press_gain", "gains")
        return cls.from_contacts(
            take(arrays, "xy_mm"),
            take(arrays, "force_n"),
            take(arrays, "tip_radius_mm"),
            1.0 if gains is None else gains,
        )

    @property
    def contact(self) -> np.ndarray:
        return np.asarray(self.force_n > 0)

    @classmethod
    def from_contacts(cls, xy_mm: Any, force_n: Any, tip_radius_mm: Any, gains: Any = 1.0) -> FsrPresses:
        """A user's presses, validated: ``xy_mm`` (B, 2), ``force_n`` (B,) >= 0, ``tip_radius_mm``
        (B,) or one value > 0, ``gains`` (B, 6), (6,) or one value > 0 (1: a nominal film)."""
        force = np.asarray(force_n, dtype=np.float64)
        if force.ndim != 1:
            raise InputError(f"force_n: expected shape (B,), got {force.shape}")
        b = len(force)
        xy = np.asarray(xy_mm, dtype=np.float64)
        if xy.shape != (b, 2):
            raise InputError(f"xy_mm: expected shape ({b}, 2), got {xy.shape}")
        try:
            tip = np.broadcast_to(np.asarray(tip_radius_mm, dtype=np.float64), (b,)).copy()
            gain = np.broadcast_to(np.asarray(gains, dtype=np.float64), (b, N_SENSORS)).copy()
        except ValueError:
            raise InputError(
                f"tip_radius_mm / gains: expected one value or shapes ({b},) / ({b}, {N_SENSORS}), got "
                f"{np.shape(tip_radius_mm)} / {np.shape(gains)}"
            ) from None
        for name, arr in (("xy_mm", xy), ("force_n", force), ("tip_radius_mm", tip), ("gains", gain)):
            if not np.isfinite(arr).all():
                raise InputError(f"{name}: contains NaN or inf")
        if (force < 0).any():
            raise InputError("force_n: a negative force is not a press (0 = no contact)")
        if (tip[force > 0] <= 0).any():
            raise InputError("tip_radius_mm: a press needs a positive tip radius")
        if (gain <= 0).any():
            raise InputError("gains: part gains must be positive")
        return cls(xy, force, tip, gain)


class PressGenerator(StimulusGenerator[FsrPresses]):
    """Draws frames from the ``[fsr.stimulus]`` and ``[fsr.film]`` distributions; ``noise=False``
    presses every frame on a nominal film (every gain 1, or a calibrated film's gains) without
    repeatability. ``model`` gives the truth ``sensor_force`` (its physics stage)."""

    def __init__(self, config: FsrConfig, model: SensorModel[FsrPresses], noise: bool = True) -> None:
        self.config = config
        self.model = model
        self.noise = noise

    def draw(self, n: int, rng: np.random.Generator) -> FsrPresses:
        cfg = self.config
        contacts = self.draw_contacts(n, rng)
        film_id, gain = self.draw_films(n, rng)
        z_rep = _unit_draw(rng, (n, N_SENSORS), cfg.film.distribution)
        z_adc = rng.standard_normal((n, N_SENSORS))  # drawn always: the stream does not depend on noise
        unusual = self.draw_unusual(contacts, rng) if cfg.stimulus.unusual else None
        press_gain = gain * (1.0 + cfg.film.repeatability * z_rep) if self.noise else gain
        return FsrPresses(contacts["xy"], contacts["force"], contacts["tip"], press_gain, film_id, gain, z_adc, unusual)

    def draw_contacts(self, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Contact flag, centre, force and tip radius of ``n`` frames."""
        st, lay = self.config.stimulus, self.config.layout
        contact = rng.random(n) >= st.no_contact_fraction
        inside = rng.random(n) < st.inside_fraction
        half = lay.size_mm / 2.0 - st.edge_margin_mm
        xy = rng.uniform(-half, half, size=(n, 2))
        # inside the triangles: pick a triangle, then a uniform point (reflected square sampling)
        tri = triangle_vertices(lay)[rng.integers(0, len(TRIANGLES), size=n)]
        u = rng.random((n, 2))
        flip = u.sum(axis=1) > 1.0
        u[flip] = 1.0 - u[flip]
        in_xy = tri[:, 0] + u[:, :1] * (tri[:, 1] - tri[:, 0]) + u[:, 1:] * (tri[:, 2] - tri[:, 0])
        xy = np.where(inside[:, None], in_xy, xy)
        lo, hi = st.force_range_n
        force = np.exp(rng.uniform(math.log(lo), math.log(hi), size=n))  # lo > 0 (validated)
        tip = np.asarray(st.tip_radii_mm, dtype=np.float64)[rng.integers(0, len(st.tip_radii_mm), size=n)]
        xy = np.where(contact[:, None], xy, 0.0)
        force = np.where(contact, force, 0.0)
        tip = np.where(contact, tip, 0.0)
        return {"contact": contact, "xy": xy, "force": force, "tip": tip}

    def draw_films(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(film id per frame (n,), film gains per frame (n, 6))."""
        film = self.config.film
        per = film.frames_per_film
        n_films = max(1, -(-n // per))
        ids = rng.integers(0, 2**62, size=n_films, dtype=np.int64)
        if film.gains is not None or not self.noise:
            gains = np.ones((n_films, N_SENSORS)) if film.gains is None else np.tile(film.gains, (n_films, 1))
        else:
            gains = np.stack([film_gains(int(i), film) for i in ids])
        index = np.arange(n) // per
        return ids[index], gains[index]

    def draw_unusual(self, contacts: dict[str, np.ndarray], rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Second presses and flat indenters, drawn after everything else (scenes without them keep
        their random stream): a second press is a fresh round press anywhere on the film."""
        st = self.config.stimulus
        n = len(contacts["contact"])
        second = self.draw_contacts(n, rng)
        has_second = contacts["contact"] & (rng.random(n) < st.second_press_fraction)
        flat = contacts["contact"] & (rng.random(n) < st.flat_fraction)
        radius = rng.uniform(st.flat_radius_mm[0], st.flat_radius_mm[1], size=n)
        # a second press always presses (draw_contacts may have drawn "no contact" for it)
        force = np.where(second["force"] > 0, second["force"], np.sqrt(np.prod(st.force_range_n)))
        tip = np.where(second["tip"] > 0, second["tip"], float(np.median(st.tip_radii_mm)))
        return {
            "second": has_second,
            "second_xy": np.where(has_second[:, None], second["xy"], 0.0),
            "second_force": np.where(has_second, force, 0.0),
            "second_tip": np.where(has_second, tip, 0.0),
            "flat": flat,
            "flat_radius": np.where(flat, radius, 0.0),
        }

    def truth_specs(self, wanted: tuple[str, ...]) -> dict[str, ArraySpec]:
        specs: dict[str, ArraySpec] = {}
        if "truth" in wanted:
            specs["xy_mm"] = ArraySpec((2,), "float32", "contact centre (mm, film centre origin); 0 if none")
            specs["force_n"] = ArraySpec((), "float32", "applied force (N); 0 = no contact")
        if "sensor_force" in wanted:
            specs["sensor_force_n"] = ArraySpec((N_SENSORS,), "float32", "noise-free disc loads (N)")
        if "latent" in wanted:
            specs["latent_film_id"] = ArraySpec((), "int64", "film id (gains = film_gains(id))")
            specs["latent_gain"] = ArraySpec((N_SENSORS,), "float32", "the film's part gains")
            specs["latent_press_gain"] = ArraySpec((N_SENSORS,), "float32", "gains of this press (with repeatability)")
            specs["latent_xy_mm"] = ArraySpec((2,), "float32", "contact centre (mm)")
            specs["latent_force_n"] = ArraySpec((), "float32", "applied force (N)")
            specs["latent_tip_radius_mm"] = ArraySpec((), "float32", "indenter tip radius (mm); 0 if none")
            specs["latent_contact"] = ArraySpec((), "bool", "a contact is present")
            if self.config.stimulus.unusual:
                specs["latent_n_presses"] = ArraySpec((), "int8", "simultaneous presses (0, 1 or 2)")
                specs["latent_flat"] = ArraySpec((), "bool", "the first press is a large flat indenter")
                specs["latent_flat_radius_mm"] = ArraySpec((), "float32", "flat indenter radius (mm); 0 if none")
                specs["latent_second_xy_mm"] = ArraySpec((2,), "float32", "second press centre (mm); 0 if none")
                specs["latent_second_force_n"] = ArraySpec((), "float32", "second press force (N); 0 if none")
        return specs

    def truth(self, stimulus: FsrPresses, wanted: tuple[str, ...]) -> dict[str, np.ndarray]:
        out: dict[str, np.ndarray] = {}
        if "truth" in wanted:
            out["xy_mm"] = stimulus.xy_mm.astype(np.float32)
            out["force_n"] = stimulus.force_n.astype(np.float32)
        if "sensor_force" in wanted:
            out["sensor_force_n"] = self.model.physics(stimulus).astype(np.float32)
        if "latent" in wanted:
            if stimulus.film_id is None or stimulus.film_gain is None:
                raise ValueError("a user's presses have no film: latent outputs need drawn frames")
            out["latent_film_id"] = stimulus.film_id.astype(np.int64)
            out["latent_gain"] = stimulus.film_gain.astype(np.float32)
            out["latent_press_gain"] = stimulus.press_gain.astype(np.float32)
            out["latent_xy_mm"] = stimulus.xy_mm.astype(np.float32)
            out["latent_force_n"] = stimulus.force_n.astype(np.float32)
            out["latent_tip_radius_mm"] = stimulus.tip_radius_mm.astype(np.float32)
            out["latent_contact"] = stimulus.contact.astype(np.bool_)
            unusual = stimulus.unusual
            if unusual is not None:
                out["latent_n_presses"] = (stimulus.contact.astype(np.int8) + unusual["second"]).astype(np.int8)
                out["latent_flat"] = unusual["flat"]
                out["latent_flat_radius_mm"] = unusual["flat_radius"].astype(np.float32)
                out["latent_second_xy_mm"] = unusual["second_xy"].astype(np.float32)
                out["latent_second_force_n"] = unusual["second_force"].astype(np.float32)
        return out
