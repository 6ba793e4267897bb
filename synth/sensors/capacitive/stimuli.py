"""Presses on the capacitive array: contacts from the shape library, their load over the frames,
the readout's drift; rasterised into the surface pressure the sensor model takes.

A :class:`Presses` stimulus is a batch of presses of ``F`` frames: the surface pressure (kPa) on the
padded fine lattice of every frame, the common offset drift of every frame, and (for generated
presses) the true contact mask and the contact list. Any user pressure field becomes a stimulus
with :meth:`Presses.from_field`.

Contact parameters are drawn generically: every field of ``synth.stimuli.ContactBatch`` beyond the
centre takes the range of the same name from its ``StimulusKind`` (0 where the kind has none), so
kinds added to the shape library need no change here.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from synth.errors import InputError
from synth.sensors.arrays import optional, take
from synth.sensors.base import ArraySpec
from synth.sensors.capacitive.config import CapacitiveConfig
from synth.sensors.model import SensorModel, StimulusGenerator
from synth.sensors.strips.config import StimulusKind
from synth.stimuli import KINDS, ContactBatch, rasterize, window_size

__all__ = ["CONTACT_PARAMS", "PressGenerator", "Presses", "half_sine"]

#: ContactBatch fields drawn from each kind's ranges (the centre is drawn apart)
CONTACT_PARAMS: tuple[str, ...] = tuple(
    f.name for f in dataclasses.fields(ContactBatch) if f.name not in ("x_mm", "y_mm")
)


def half_sine(frames: int) -> np.ndarray:
    """Load fraction of a press over its frames: ``sin(pi k / (F + 1))``, ``k = 1..F`` (one frame: 1)."""
    return np.sin(np.pi * np.arange(1, frames + 1) / (frames + 1))


@dataclass(frozen=True)
class Presses:
    """``field_kpa`` (B, F, Hp, Wp) float32 surface pressure on the padded lattice, ``drift_v`` (B, F)
    common offset; for generated presses the true ``mask`` (B, F, H, W), the ``contacts`` (latent
    arrays, (B, K) each) and every contact's ``load`` fraction (B, F, K)."""

    field_kpa: np.ndarray
    drift_v: np.ndarray
    mask: np.ndarray | None = None
    contacts: dict[str, np.ndarray] = field(default_factory=dict)
    load: np.ndarray | None = None

    #: the arrays of :meth:`from_arrays` (a user's ``.npz``)
    FIELDS: ClassVar[dict[str, str]] = {
        "field_kpa": "(B, F, Hp, Wp) surface pressure (kPa) of every frame, padded lattice (alias 'pressure')",
        "drift_v": "(B, F) common offset drift of every frame in V, optional (default 0)",
    }

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], config: CapacitiveConfig) -> Presses:
        """A stimulus from named arrays (:attr:`FIELDS`), validated."""
        return cls.from_field(take(arrays, "field_kpa", "pressure"), config, optional(arrays, "drift_v"))

    @classmethod
    def from_field(cls, field_kpa: Any, config: CapacitiveConfig, drift_v: Any = None) -> Presses:
        """A user's pressure field (kPa, (B, F, Hp, Wp) on ``geometry.lattice_shape``), validated."""
        arr = np.asarray(field_kpa)
        shape = config.geometry.lattice_shape
        if arr.ndim != 4 or arr.shape[2:] != shape:
            raise InputError(f"pressure field: expected shape (B, F, {shape[0]}, {shape[1]}), got {arr.shape}")
        if not np.issubdtype(arr.dtype, np.number) or not np.isfinite(arr).all():
            raise InputError("pressure field: must be finite numbers (kPa)")
        if (arr < 0).any():
            raise InputError("pressure field: negative pressure (kPa) is not a contact (the cover cannot pull)")
        drift = np.zeros(arr.shape[:2]) if drift_v is None else np.asarray(drift_v, dtype=np.float64)
        if drift.shape != arr.shape[:2] or not np.isfinite(drift).all():
            raise InputError(f"drift_v: expected finite values of shape {arr.shape[:2]}, got {drift.shape}")
        return cls(field_kpa=np.ascontiguousarray(arr, dtype=np.float32), drift_v=drift)

    def __len__(self) -> int:
        return int(self.field_kpa.shape[0])


def _window(config: CapacitiveConfig, kind: str, specs: list[StimulusKind]) -> int:
    """Lattice cells per side of a window that holds any contact of ``kind`` drawn from ``specs``."""
    h, e_star = config.geometry.h_mm, config.cover.e_star_mpa
    return max(
        window_size(
            kind,
            h,
            e_star,
            radius_mm=s.radius_mm[1],
            force_n=s.force_n[1],
            width_mm=s.width_mm[1],
            length_mm=s.length_mm[1],
            min_length_mm=s.length_mm[0],
        )
        for s in specs
    )


class PressGenerator(StimulusGenerator[Presses]):
    """Draws presses from a scene's ``[capacitive.stimuli]``; truth through the sensor ``model``
    (the cell loads are its physics stage)."""

    def __init__(self, config: CapacitiveConfig, model: SensorModel[Presses]) -> None:
        self.config = config
        self.model = model
        st = config.stimuli
        self.k_max = st.count[1]
        by_kind: dict[str, list[StimulusKind]] = {}
        for spec in st.kinds:
            by_kind.setdefault(spec.kind, []).append(spec)
        self.windows = {kind: _window(config, kind, specs) for kind, specs in by_kind.items()}

    # ---- drawing ----------------------------------------------------------------------------------

    def draw(self, n: int, rng: np.random.Generator) -> Presses:
        contacts = self.draw_contacts(n, rng)
        drift = self.draw_drift(n, self.config.stimuli.frames, rng)
        load = half_sine(self.config.stimuli.frames)[None, :, None] * contacts["present"][:, None, :]
        return self.press(contacts, load, drift)

    def draw_contacts(self, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Contact list padded to ``(n, K)``: ``count``, ``present``, ``kind`` (index into KINDS, -1
        none), ``x_mm``, ``y_mm`` and every ContactBatch parameter (``force_n`` is the peak force)."""
        st, g = self.config.stimuli, self.config.geometry
        k = self.k_max
        count = rng.integers(st.count[0], st.count[1] + 1, size=n)
        count[rng.random(n) < st.empty_fraction] = 0
        weights = np.array([s.weight for s in st.kinds])
        spec = rng.choice(len(st.kinds), size=(n, k), p=weights / weights.sum())
        u = rng.random((n, k, 3 + len(CONTACT_PARAMS)))
        width_x, width_y = g.n_cols * g.pitch_mm, g.n_rows * g.pitch_mm
        x = st.margin_mm + u[..., 0] * (width_x - 2 * st.margin_mm)
        y = st.margin_mm + u[..., 1] * (width_y - 2 * st.margin_mm)
        if st.sweep_cells:  # a rig: press i on cell i mod N*M, the centre of its square
            cell = np.arange(n) % (g.n_rows * g.n_cols)
            x[:, 0] = (cell % g.n_cols + 0.5) * g.pitch_mm
            y[:, 0] = (cell // g.n_cols + 0.5) * g.pitch_mm
        if st.pair_distance_mm[1] > 0 and k >= 2:
            x[:, 1], y[:, 1] = self._pair(x[:, 0], y[:, 0], u[:, 1, 0], u[:, 1, 2], width_x, width_y)
        params: dict[str, np.ndarray] = {}
        for col, name in enumerate(CONTACT_PARAMS, start=3):
            lo = np.array([_range(s, name)[0] for s in st.kinds])[spec]
            hi = np.array([_range(s, name)[1] for s in st.kinds])[spec]
            params[name] = lo + u[..., col] * (hi - lo)
        present = np.arange(k)[None, :] < count[:, None]
        code = np.array([KINDS.index(s.kind) for s in st.kinds])[spec]
        return {"count": count, "present": present, "kind": np.where(present, code, -1), "x_mm": x, "y_mm": y, **params}

    def _pair(
        self, x0: np.ndarray, y0: np.ndarray, u_dist: np.ndarray, u_dir: np.ndarray, width_x: float, width_y: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The second contact's centre at a drawn distance from the first: the drawn direction, else
        the opposite one, else clipped into the allowed area (then nearer than drawn)."""
        st = self.config.stimuli
        lo, hi = st.pair_distance_mm
        dist = lo + u_dist * (hi - lo)
        theta = 2 * np.pi * u_dir
        m = st.margin_mm
        best_x, best_y = x0 + dist * np.cos(theta), y0 + dist * np.sin(theta)
        for turn in (np.pi, np.pi / 2, -np.pi / 2):
            inside = (best_x >= m) & (best_x <= width_x - m) & (best_y >= m) & (best_y <= width_y - m)
            alt_x, alt_y = x0 + dist * np.cos(theta + turn), y0 + dist * np.sin(theta + turn)
            best_x, best_y = np.where(inside, best_x, alt_x), np.where(inside, best_y, alt_y)
        return np.clip(best_x, m, width_x - m), np.clip(best_y, m, width_y - m)

    def draw_drift(self, n: int, frames: int, rng: np.random.Generator) -> np.ndarray:
        """Common offset (V) of every frame: a press's offset plus a constant rate."""
        r = self.config.readout
        start = r.drift_v * rng.standard_normal((n, 1))
        rate = r.drift_v_per_frame * rng.standard_normal((n, 1))
        return start + rate * np.arange(frames)[None, :]

    # ---- rasterising ------------------------------------------------------------------------------

    def press(self, contacts: dict[str, np.ndarray], load: np.ndarray, drift: np.ndarray) -> Presses:
        """The stimulus of ``contacts`` pressed with ``load`` (B, F, K): the fraction of each
        contact's peak force in every frame (0: not touching; absent contacts are forced to 0)."""
        load = np.where(contacts["present"][:, None, :], load, 0.0)
        g = self.config.geometry
        n, frames, k = load.shape
        hp, wp = g.lattice_shape
        ny, nx = g.image_shape
        pad, h = g.pad_cells, g.h_mm
        frac = self.config.stimuli.mask_fraction
        field_flat = np.zeros((n * frames, hp * wp + 1), dtype=np.float32)  # last column: out of lattice
        mask_flat = np.zeros((n * frames, ny * nx + 1), dtype=bool)
        for kind, size in self.windows.items():
            sel = contacts["present"] & (contacts["kind"] == KINDS.index(kind))
            for slot in range(k):
                presses = np.flatnonzero(sel[:, slot])
                if not len(presses):
                    continue
                lam = load[presses, :, slot]  # (m, F)
                which, frame = np.nonzero(lam > 0)
                if not len(which):
                    continue
                b = presses[which]
                batch = ContactBatch(
                    **{
                        "x_mm": contacts["x_mm"][b, slot] + pad * h,  # lattice coordinates
                        "y_mm": contacts["y_mm"][b, slot] + pad * h,
                        **{name: contacts[name][b, slot] for name in CONTACT_PARAMS},
                    }
                )
                batch = dataclasses.replace(batch, force_n=batch.force_n * lam[which, frame])
                win = rasterize(kind, batch, h, size, self.config.cover.e_star_mpa)
                rows = win.y0[:, None] + np.arange(size)[None, :]  # lattice rows of each window
                cols = win.x0[:, None] + np.arange(size)[None, :]
                target = b * frames + frame
                inside = (
                    (rows[:, :, None] >= 0)
                    & (rows[:, :, None] < hp)
                    & (cols[:, None, :] >= 0)
                    & (cols[:, None, :] < wp)
                )
                index = np.where(inside, rows[:, :, None] * wp + cols[:, None, :], hp * wp)
                # one window per (frame, slot): no index repeats within this assignment but the dump column
                field_flat[target[:, None], index.reshape(len(b), -1)] += win.values.reshape(len(b), -1).astype(
                    np.float32
                )
                # the true mask: where the contact presses at least ``frac`` of its own mean pressure
                positive = win.values > 0
                mean = win.values.sum(axis=(1, 2)) / np.maximum(positive.sum(axis=(1, 2)), 1)
                pressed = win.values >= frac * mean[:, None, None]
                ri, ci = rows - pad, cols - pad
                in_image = (ri[:, :, None] >= 0) & (ri[:, :, None] < ny) & (ci[:, None, :] >= 0) & (ci[:, None, :] < nx)
                m_index = np.where(in_image & pressed, ri[:, :, None] * nx + ci[:, None, :], ny * nx)
                mask_flat[target[:, None], m_index.reshape(len(b), -1)] = True
        return Presses(
            field_kpa=field_flat[:, :-1].reshape(n, frames, hp, wp),
            drift_v=drift,
            mask=mask_flat[:, :-1].reshape(n, frames, ny, nx),
            contacts=contacts,
            load=load,
        )

    # ---- truth ------------------------------------------------------------------------------------

    def truth_specs(self, wanted: tuple[str, ...]) -> dict[str, ArraySpec]:
        g = self.config.geometry
        frames, k = self.config.stimuli.frames, self.k_max
        cells = (frames, g.n_rows, g.n_cols)
        image = (frames, *g.image_shape)
        specs: dict[str, ArraySpec] = {}
        if "cell_load" in wanted:
            specs["cell_load"] = ArraySpec(cells, "float32", "true load on every tab (N)")
        if "image" in wanted:
            specs["force_image"] = ArraySpec(image, "float32", "surface force on every fine-lattice cell (N)")
            specs["contact_mask"] = ArraySpec(image, "bool", "true contact mask on the fine lattice")
        if "latent" in wanted:
            specs.update(
                latent_n_contacts=ArraySpec((), "int8", "contacts in the press"),
                latent_kind=ArraySpec((k,), "int8", f"stimulus kind index into {list(KINDS)}, -1 = no contact"),
                latent_xy_mm=ArraySpec((k, 2), "float32", "contact centre (x, y) in mm from the array's corner"),
                latent_load=ArraySpec((frames, k), "float32", "each contact's share of its peak force per frame"),
                latent_drift_v=ArraySpec((frames,), "float32", "common offset drift per frame (V)"),
            )
            for name in CONTACT_PARAMS:
                what = "peak force (N)" if name == "force_n" else name
                specs[f"latent_{name}"] = ArraySpec((k,), "float32", f"contact {what}")
        return specs

    def truth(self, stimulus: Presses, wanted: tuple[str, ...]) -> dict[str, np.ndarray]:
        g = self.config.geometry
        out: dict[str, np.ndarray] = {}
        if "cell_load" in wanted:
            out["cell_load"] = self.model.physics(stimulus)
        if "image" in wanted:
            pad = g.pad_cells
            ny, nx = g.image_shape
            pressure = stimulus.field_kpa[:, :, pad : pad + ny, pad : pad + nx]
            out["force_image"] = pressure * np.float32(g.h_mm**2 * 1e-3)  # kPa x mm^2 -> N
            if stimulus.mask is None:
                raise ValueError("a user's pressure field has no contact mask")
            out["contact_mask"] = stimulus.mask
        if "latent" in wanted:
            c = stimulus.contacts
            present = c["present"]
            out.update(
                latent_n_contacts=c["count"],
                latent_kind=c["kind"],
                latent_xy_mm=np.where(present[..., None], np.stack([c["x_mm"], c["y_mm"]], -1), 0.0),
                latent_load=stimulus.load if stimulus.load is not None else np.zeros(0),
                latent_drift_v=stimulus.drift_v,
            )
            for name in CONTACT_PARAMS:
                out[f"latent_{name}"] = np.where(present, c[name], 0.0)
        return out


def _range(spec: StimulusKind, name: str) -> tuple[float, float]:
    value = getattr(spec, name, None)
    if isinstance(value, tuple) and len(value) == 2:
        return (float(value[0]), float(value[1]))
    return (0.0, 0.0)
