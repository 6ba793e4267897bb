"""Contacts on the strip array: drawn from the scene's shape library, rasterised where there is load.

A :class:`StripContacts` stimulus is a batch of frames of up to ``K`` contacts each (the contact
list, ``(B, K)`` arrays), every strip's sensitivity gain ``(B, S)`` and the contacts rasterised
into pressure windows of the fine lattice (``synth.stimuli``): the sensor model works only where
there is load. A user's pressure field on the whole lattice is a :class:`PressureField`.

:class:`ContactGenerator` draws them (``draw(n, rng)``: contacts, then gains - the random stream of
the simulator this replaces, so datasets keep their bytes) and reports the ground truth: the
intersection map (mean surface pressure over every pitch cell), the fine field, the contact list.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np

from synth.errors import InputError
from synth.sensors.arrays import optional, take
from synth.sensors.base import ArraySpec
from synth.sensors.model import StimulusGenerator
from synth.sensors.strips.config import DRAWN_PARAMS, ContactObject, StripsConfig, draw_except
from synth.sensors.strips.layouts import StripLayout
from synth.stimuli import DETAIL, KINDS, ContactBatch, Windows, rasterize, window_cells, window_size

__all__ = [
    "OUTPUTS",
    "SHAPED_KINDS",
    "WINDOW_LADDER",
    "ContactGenerator",
    "PressureField",
    "StripContacts",
    "StripObserver",
    "contact_pad",
]

OUTPUTS: dict[str, str] = {
    "readings": "strip readings (V), rows then columns: (N+M,)",
    "pressure": "intersection map: mean surface pressure over each pitch cell (kPa), (N, M)",
    "field": "fine surface pressure field (kPa), (N*s, M*s)",
    "latent": "contact list, strip gains and noise-free readings of every frame",
}

#: kinds of the shape library beyond the seed's four (see ``ContactGenerator.shaped``)
SHAPED_KINDS = ("ring", "terminal", "blob")
#: window sizes (lattice cells per side) that contacts are grouped into, each kind capped at its own
#: largest window: few sizes (each caches its operator tables), none much larger than needed
WINDOW_LADDER = (12, 16, 22, 30, 40, 54, 72, 96)

#: one rasterised group: the (frame, slot) of every window and the windows
WindowGroup = tuple[tuple[np.ndarray, np.ndarray], Windows]


@dataclass(frozen=True)
class StripContacts:
    """Drawn frames: ``contacts`` (``count`` (B,), ``present``/``kind``/``x_mm``/``y_mm``/the drawn
    parameters (B, K), ``detail`` (B, K, DETAIL), ``twin`` (B,)), ``gains`` (B, S) float32 and the
    contacts' pressure ``windows`` (empty when nothing needs the pressure: latent-only scenes)."""

    contacts: dict[str, np.ndarray]
    gains: np.ndarray
    windows: list[WindowGroup] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.gains)


@dataclass(frozen=True)
class PressureField:
    """A user's surface pressure ``field_kpa`` (B, N*s, M*s) on the array's lattice and the strips'
    ``gains`` (B, S) (1: a nominal device)."""

    field_kpa: np.ndarray
    gains: np.ndarray

    #: the arrays of :meth:`from_arrays` (a user's ``.npz``)
    FIELDS: ClassVar[dict[str, str]] = {
        "field_kpa": "(B, N*s, M*s) surface pressure in kPa on the fine lattice (alias 'pressure')",
        "gains": "(B, S) per-strip sensitivity gains, optional (default 1: a nominal device)",
    }

    def __len__(self) -> int:
        return len(self.gains)

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], config: StripsConfig) -> PressureField:
        """A stimulus from named arrays (:attr:`FIELDS`), validated."""
        return cls.from_field(take(arrays, "field_kpa", "pressure"), config, optional(arrays, "gains"))

    @classmethod
    def from_field(cls, field_kpa: Any, config: StripsConfig, gains: Any = None) -> PressureField:
        """Validated: the field's shape and values (the model checks them again), positive finite gains."""
        arr = np.asarray(field_kpa)
        g = config.geometry
        shape = (g.n_rows * g.samples_per_pitch, g.n_cols * g.samples_per_pitch)
        if arr.ndim != 3 or arr.shape[1:] != shape:
            raise InputError(f"pressure field: expected shape (B, {shape[0]}, {shape[1]}), got {arr.shape}")
        strips = StripLayout(g).n_strips
        if gains is None:
            gains = np.ones((len(arr), strips), dtype=np.float32)
        gains = np.asarray(gains, dtype=np.float32)
        if gains.shape != (len(arr), strips) or not np.isfinite(gains).all() or (gains <= 0).any():
            raise InputError(
                f"gains: expected positive finite values of shape ({len(arr)}, {strips}), got {gains.shape}"
            )
        return cls(np.asarray(arr, dtype=np.float32), gains)


def contact_pad(config: StripsConfig) -> tuple[dict[str, int], int]:
    """The window size of every stimulus kind (large enough for every entry of that kind) and the
    lattice padding (cells) the sensor model needs for contacts at or past the array's border."""
    g = config.geometry
    h = g.pitch_mm / g.samples_per_pitch
    e_star = config.layers.e_star_mpa
    window: dict[str, int] = {}
    for spec in config.stimuli.kinds:
        size = window_size(
            spec.kind,
            h,
            e_star,
            radius_mm=spec.radius_mm[1],
            force_n=spec.force_n[1],
            width_mm=spec.width_mm[1],
            length_mm=spec.length_mm[1],
            min_length_mm=spec.length_mm[0],
        )
        window[spec.kind] = max(size, window.get(spec.kind, 0))
    reach = max(0.0, -config.stimuli.margin_mm) / h  # centres may lie this many cells outside the array
    return window, int(np.ceil(reach)) + max(window.values(), default=0)


class StripObserver(Protocol):
    """What the truth needs of the sensor model: the intersection map and the clean readings."""

    def pressure_map(self, stimulus: StripContacts) -> np.ndarray: ...

    def forward(self, stimulus: StripContacts, rng: np.random.Generator | None = None) -> np.ndarray: ...


class ContactGenerator(StimulusGenerator[StripContacts]):
    """Draws frames of contacts and gains from the ``[strips.stimuli]`` distribution.

    ``rasterize`` (default on) rasterises the contacts into pressure windows as they are drawn;
    ``model`` (the scene's :class:`~synth.sensors.strips.sensor.StripModel`) computes the truth
    that needs the mechanics (intersection map, clean readings).
    """

    def __init__(self, config: StripsConfig, model: StripObserver | None = None, rasterize: bool = True) -> None:
        self.config = config
        self.model = model
        self.rasterize = rasterize
        g = config.geometry
        self.k_max = config.stimuli.count[1]
        self.field_pitch_mm = g.pitch_mm / g.samples_per_pitch
        self.field_shape = (g.n_rows * g.samples_per_pitch, g.n_cols * g.samples_per_pitch)
        self.window, self.pad = contact_pad(config)
        # scenes that use only the first four kinds, untilted, draw (and store) exactly what they did
        # before the shape library grew: their datasets stay identical bit for bit
        self.shaped = any(s.kind in SHAPED_KINDS or s.tilt != (0.0, 0.0) for s in config.stimuli.kinds)
        self.layout = StripLayout(g)

    # -- drawing -------------------------------------------------------------------------------

    def draw(self, n: int, rng: np.random.Generator) -> StripContacts:
        contacts = self.draw_contacts(n, rng)
        gains = self.draw_gains(n, rng)
        return StripContacts(contacts, gains, self.windows(contacts) if self.rasterize else [])

    def draw_contacts(self, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Contact parameters, padded to ``(n, k_max)``; the same draws whatever outputs are wanted."""
        st = self.config.stimuli
        g = self.config.geometry
        k = self.k_max
        if st.count_weights:
            weights = np.asarray(st.count_weights, dtype=np.float64)
            count = st.count[0] + rng.choice(len(weights), size=n, p=weights / weights.sum())
        else:
            count = rng.integers(st.count[0], st.count[1] + 1, size=n)
        count[rng.random(n) < st.empty_fraction] = 0
        weights = np.array([s.weight for s in st.kinds])
        spec_index = rng.choice(len(st.kinds), size=(n, k), p=weights / weights.sum())
        u = rng.random((n, k, 7))
        width_y, width_x = g.n_rows * g.pitch_mm, g.n_cols * g.pitch_mm
        x = st.margin_mm + u[..., 0] * (width_x - 2 * st.margin_mm)
        y = st.margin_mm + u[..., 1] * (width_y - 2 * st.margin_mm)

        if st.object is not None and st.object.part_kinds:
            spec_index[:] = np.arange(k)  # part j is kinds[j]; the weighted draw above keeps the stream
        twin = (count >= 2) & (rng.random(n) < st.twin_fraction)
        # the shape library's extra parameters are drawn after everything the first four kinds use
        extra = rng.random((n, k, 2 + DETAIL)) if self.shaped else np.zeros((n, k, 2 + DETAIL))
        uniforms = np.concatenate([u[..., 2:], extra[..., :2]], axis=-1)

        def draw(col: int, attr: str) -> np.ndarray:
            out = np.empty((n, k))
            for index, spec in enumerate(st.kinds):
                sel = spec_index == index
                lo, hi = getattr(spec, attr)
                out[sel] = draw_except(uniforms[..., col][sel], lo, hi, spec.holdouts(attr))
            return out

        params = {attr: draw(col, attr) for col, attr in enumerate(DRAWN_PARAMS)}
        params["detail"] = extra[..., 2:]
        if twin.any():  # every contact copies the first one's kind and parameters
            spec_index[twin] = spec_index[twin, :1]
            for value in params.values():
                value[twin] = value[twin, :1]
        if st.object is not None:  # drawn after everything else: scenes without an object keep their stream
            x, y = self._place_object(st.object, params["angle_deg"], rng)
        present = np.arange(k)[None, :] < count[:, None]
        kind_code = np.array([KINDS.index(s.kind) for s in st.kinds])[spec_index]
        return {
            "count": count,
            "present": present,
            "spec": spec_index,
            "kind": np.where(present, kind_code, -1),
            "x_mm": x,
            "y_mm": y,
            "twin": twin,
            **params,
        }

    def _place_object(
        self, obj: ContactObject, angle_deg: np.ndarray, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray]:
        """Centres (x, y) of the parts of one object per frame (:class:`ContactObject`); turns each
        part's ``angle_deg`` (in place) with the object."""
        st, g = self.config.stimuli, self.config.geometry
        n, k = angle_deg.shape
        u = rng.random((n, 4))
        # without holes draw_except is lo + u (hi - lo): objects without a rotation holdout draw as before
        rotation = draw_except(u[:, 0], *obj.rotation_deg, list(obj.rotation_holdout))
        scale = obj.scale[0] + u[:, 1] * (obj.scale[1] - obj.scale[0])
        offsets = np.asarray(obj.offsets_mm[:k], dtype=np.float64)
        theta = np.deg2rad(rotation)[:, None]
        ox = scale[:, None] * (offsets[None, :, 0] * np.cos(theta) - offsets[None, :, 1] * np.sin(theta))
        oy = scale[:, None] * (offsets[None, :, 0] * np.sin(theta) + offsets[None, :, 1] * np.cos(theta))
        angle_deg += rotation[:, None]

        def centre(v: np.ndarray, offset: np.ndarray, side_mm: float) -> np.ndarray:
            # every part inside [margin, side - margin]; the config checks that the parts fit
            lo = st.margin_mm - offset.min(axis=1)
            hi = side_mm - st.margin_mm - offset.max(axis=1)
            return lo + v * np.maximum(hi - lo, 0.0)

        cx = centre(u[:, 2], ox, g.n_cols * g.pitch_mm)
        cy = centre(u[:, 3], oy, g.n_rows * g.pitch_mm)
        return cx[:, None] + ox, cy[:, None] + oy

    def draw_gains(self, n: int, rng: np.random.Generator) -> np.ndarray:
        spread = self.config.piezo.gain_spread
        # clipped so that a 6-sigma draw cannot make a strip's sensitivity vanish or flip sign
        return np.clip(1.0 + spread * rng.standard_normal((n, self.layout.n_strips)), 0.5, 1.5).astype(np.float32)

    def windows(self, contacts: dict[str, np.ndarray]) -> list[WindowGroup]:
        """Rasterised windows per stimulus kind, with the (frame, slot) of each window."""
        out = []
        h = self.field_pitch_mm
        e_star = self.config.layers.e_star_mpa
        for kind in dict.fromkeys(s.kind for s in self.config.stimuli.kinds):
            sel = contacts["present"] & (contacts["kind"] == KINDS.index(kind))
            if not sel.any():
                continue
            frame, slot = np.nonzero(sel)
            batch = ContactBatch(**{key: contacts[key][sel] for key in ContactBatch.__dataclass_fields__})
            # contacts share a window size per bucket of the ladder: a short edge is not rasterised
            # in (nor multiplied through) the window of the longest edge the scene allows
            needed = window_cells(kind, batch, h, e_star)
            ladder = np.array([s for s in WINDOW_LADDER if s < self.window[kind]] + [self.window[kind]])
            bucket = ladder[np.minimum(np.searchsorted(ladder, needed), len(ladder) - 1)]
            for size in np.unique(bucket):
                pick = bucket == size
                fields: dict[str, Any] = {
                    key: None if getattr(batch, key) is None else getattr(batch, key)[pick]
                    for key in ContactBatch.__dataclass_fields__
                }
                part = ContactBatch(**fields)
                out.append(((frame[pick], slot[pick]), rasterize(kind, part, h, int(size), e_star)))
        return out

    def field(self, stimulus: StripContacts) -> np.ndarray:
        """The fine surface pressure field (B, N*s, M*s) float32 of drawn frames."""
        n = len(stimulus)
        ny, nx = self.field_shape
        pad = self.pad
        out = np.zeros((n, ny + 2 * pad, nx + 2 * pad), np.float32)
        for (frame, _slot), win in stimulus.windows:
            size = win.values.shape[-1]
            iy = np.clip(win.y0[:, None] + pad + np.arange(size), 0, ny + 2 * pad - 1)
            ix = np.clip(win.x0[:, None] + pad + np.arange(size), 0, nx + 2 * pad - 1)
            np.add.at(out, (frame[:, None, None], iy[:, :, None], ix[:, None, :]), win.values.astype(np.float32))
        return out[:, pad : pad + ny, pad : pad + nx]

    # -- truth ---------------------------------------------------------------------------------

    def truth_specs(self, wanted: tuple[str, ...]) -> dict[str, ArraySpec]:
        g = self.config.geometry
        n, m, k = g.n_rows, g.n_cols, self.k_max
        specs: dict[str, ArraySpec] = {}
        if "pressure" in wanted:
            specs["pressure"] = ArraySpec((n, m), "float32", OUTPUTS["pressure"])
        if "field" in wanted:
            specs["field"] = ArraySpec((n * g.samples_per_pitch, m * g.samples_per_pitch), "float32", OUTPUTS["field"])
        if "latent" in wanted:
            specs.update(
                latent_n_contacts=ArraySpec((), "int8", "contacts in the frame"),
                latent_kind=ArraySpec((k,), "int8", f"stimulus kind index into {list(KINDS)}, -1 = no contact"),
                latent_xy_mm=ArraySpec((k, 2), "float32", "contact centre (x, y) in mm from the array's corner"),
                latent_force_n=ArraySpec((k,), "float32", "contact force (N)"),
                latent_radius_mm=ArraySpec((k,), "float32", "sphere / punch / edge tip radius (mm)"),
                latent_width_mm=ArraySpec((k,), "float32", "block width (mm)"),
                latent_length_mm=ArraySpec((k,), "float32", "block or edge length (mm)"),
                latent_angle_deg=ArraySpec((k,), "float32", "block or edge angle (deg)"),
                latent_twin=ArraySpec((), "bool", "contacts are identical copies (ghost-ambiguous)"),
                **(
                    {
                        "latent_hole_fraction": ArraySpec((k,), "float32", "ring / terminal hole over outer radius"),
                        "latent_tilt": ArraySpec((k,), "float32", "block pressure slope along its length"),
                        "latent_detail": ArraySpec((k, DETAIL), "float32", "uniform numbers shaping a blob"),
                    }
                    if self.shaped
                    else {}
                ),
                latent_strip_gain=ArraySpec((self.layout.n_strips,), "float32", "per-strip sensitivity gain"),
            )
            if "readings" in wanted:
                channels = self.layout.n_channels
                specs["readings_clean"] = ArraySpec((channels,), "float32", "noise-free, unquantised readings (V)")
        return specs

    def truth(self, stimulus: StripContacts, wanted: tuple[str, ...]) -> dict[str, np.ndarray]:
        out: dict[str, np.ndarray] = {}
        if "pressure" in wanted:
            out["pressure"] = self._model().pressure_map(stimulus)
        if "field" in wanted:
            out["field"] = self.field(stimulus)
        if "latent" in wanted:
            contacts, f32 = stimulus.contacts, np.float32
            # the order the arrays were always written in (a shard's sidecar lists them so)
            out.update(
                latent_n_contacts=contacts["count"].astype(np.int8),
                latent_kind=contacts["kind"].astype(np.int8),
                latent_xy_mm=np.where(
                    contacts["present"][..., None], np.stack([contacts["x_mm"], contacts["y_mm"]], -1), 0
                ).astype(f32),
                latent_twin=contacts["twin"],
                latent_strip_gain=stimulus.gains,
            )
            for key in DRAWN_PARAMS if self.shaped else DRAWN_PARAMS[:5]:
                out[f"latent_{key}"] = np.where(contacts["present"], contacts[key], 0).astype(f32)
            if self.shaped:
                out["latent_detail"] = np.where(contacts["present"][..., None], contacts["detail"], 0).astype(f32)
            if "readings" in wanted:
                out["readings_clean"] = self._model().forward(stimulus)
        return out

    def _model(self) -> StripObserver:
        if self.model is None:
            raise ValueError(
                "the intersection map and clean readings need the sensor model (ContactGenerator(model=...))"
            )
        return self.model
