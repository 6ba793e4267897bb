"""Touches of the thermal fingertip: one or two objects on the grid, everything about them drawn.

A :class:`Touches` stimulus holds, per touch and pixel (``(B, P)`` float64 arrays, pixels
row-major), what the physics needs: the sensor (heat capacity ``C``, loss ``G``, heater ``Q``,
ambient), the object each pixel touches (its properties, temperature, the interface and spreading
conductances) and the contact's onset and release; real-sensor scenes (``ThermalConfig.dynamic``)
add the thermistors' lags, the heater's control, drift, build-up and the passive thermistor
(:func:`synth.sensors.thermal.touch.draw_dynamics`). A user's touch becomes a stimulus with
:meth:`Touches.from_objects`.

:class:`TouchGenerator` draws them in the random stream of the simulator it replaces (layout,
sensor, objects, then the real-sensor quantities), so datasets keep their bytes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from synth.errors import InputError
from synth.materials import FAMILIES, get_material, sample_properties
from synth.sensors.arrays import optional, take
from synth.sensors.base import ArraySpec
from synth.sensors.model import StimulusGenerator
from synth.sensors.thermal.config import ThermalConfig
from synth.sensors.thermal.physics import ABSOLUTE_ZERO_C, spreading_conductance
from synth.sensors.thermal.touch import draw_dynamics

__all__ = ["OUTPUTS", "TouchGenerator", "Touches"]

OUTPUTS: dict[str, str] = {
    "readings": "thermistor temperatures (degC) of every pixel over the record: (P, R), pixels row-major",
    "passive": "the passive (unheated) thermistor beside every pixel (degC): (P, R); needs passive.enabled",
    "latent": "per-pixel truth: material, its properties, contact, temperatures, onset, release, sensor",
}

_LATENTS: dict[str, tuple[str, str]] = {
    "latent_material": ("int16", "material index into the scene's material list, -1 = touches nothing"),
    "latent_family": ("int8", f"family index into {list(FAMILIES)}, -1 = touches nothing"),
    "latent_object": ("int8", "which object (0, 1) the pixel touches, -1 = nothing"),
    "latent_k_w_mk": ("float32", "object conductivity (W/(m K)), 0 = nothing"),
    "latent_rho_kg_m3": ("float32", "object density (kg/m^3), 0 = nothing"),
    "latent_c_j_kgk": ("float32", "object specific heat (J/(kg K)), 0 = nothing"),
    "latent_effusivity": ("float32", "object effusivity sqrt(k rho c) (W s^0.5/(m^2 K)), 0 = nothing"),
    "latent_diffusivity_mm2_s": ("float32", "object diffusivity (mm^2/s), 0 = nothing"),
    "latent_conductance_w_m2k": ("float32", "interface conductance H (W/(m^2 K)), 0 = nothing"),
    "latent_radius_mm": ("float32", "contact patch radius (mm), 0 = nothing"),
    "latent_spreading_w_m2k": ("float32", "spreading conductance k_s (W/(m^2 K)), 0 = nothing"),
    "latent_object_c": ("float32", "object temperature (degC); the ambient for pixels touching nothing"),
    "latent_v0_k": ("float32", "initial sensor-object difference V0 (K), 0 = nothing"),
    "latent_onset_s": ("float32", "contact onset (s from record start); the touch's onset for nothing"),
    "latent_release_s": ("float32", "release time (s); the touch's release for nothing"),
    "latent_heat_capacity_j_m2k": ("float32", "pixel heat capacity per area C"),
    "latent_loss_w_m2k": ("float32", "pixel loss conductance G"),
    "latent_heater_w_m2": ("float32", "heater output Q"),
    "latent_ambient_c": ("float32", "ambient temperature (degC)"),
}

_DYNAMIC_LATENTS: dict[str, tuple[str, str]] = {
    "latent_class": ("int16", "class index (the scene's classes, else its materials), -1 = touches nothing"),
    "latent_ramp_s": ("float32", "contact build-up time (s)"),
    "latent_drift_k_s": ("float32", "heated reading's drift before contact (K/s)"),
    "latent_lag_s": ("float32", "heated thermistor's lags tau_1 + tau_2 (s)"),
}


#: quantities of a user's touch that must be positive (the onset may be 0)
_POSITIVE = ("k_w_mk", "rho_kg_m3", "c_j_kgk", "conductance_w_m2k", "radius_mm", "contact_s")


def _per_touch(values: dict[str, Any]) -> tuple[dict[str, np.ndarray], int]:
    """Every value as a float64 array of one value or ``B`` (one per touch), validated, and ``B``."""
    arrays = {k: np.atleast_1d(np.asarray(v, dtype=np.float64)) for k, v in values.items()}
    b = max(len(a) for a in arrays.values())
    for name, arr in arrays.items():
        if arr.ndim != 1 or len(arr) not in (1, b):
            raise InputError(f"{name}: expected one value or shape ({b},), got {arr.shape}")
        if not np.isfinite(arr).all():
            raise InputError(f"{name}: contains NaN or inf")
    for name in _POSITIVE:
        if (arrays[name] <= 0).any():
            raise InputError(f"{name}: must be > 0")
    if (arrays["onset_s"] < 0).any():
        raise InputError("onset_s: must be >= 0 (seconds from the record's start)")
    for name in ("object_c", "ambient_c"):
        if (arrays[name] <= ABSOLUTE_ZERO_C).any():
            raise InputError(
                f"{name}: {arrays[name].min():g} degC is at or below absolute zero ({ABSOLUTE_ZERO_C} degC)"
            )
    return arrays, b


def _nominal_sensor_touch(
    config: ThermalConfig, a: dict[str, np.ndarray], mask: np.ndarray, ambient: np.ndarray
) -> dict[str, np.ndarray]:
    """The physics' quantities of user touches ``a`` ((B, P) each) on pixels ``mask`` of a sensor
    at the middle of the scene's ranges, every pixel alike."""
    sc = config.sensor
    b, p = mask.shape
    heat_capacity = np.full((b, p), float(np.mean(sc.heat_capacity_j_m2k)))
    loss = np.full((b, p), float(np.mean(sc.loss_w_m2k)))
    heater = np.full((b, p), float(np.mean(sc.heater_w_m2)))
    radius_m = a["radius_mm"] * 1e-3
    spreading = spreading_conductance(a["k_w_mk"], radius_m) if config.contact.spreading else 0.0 * radius_m
    object_c = np.where(mask, a["object_c"], ambient[:, None])
    return {
        "layout": np.where(mask, 0, -1).astype(np.int8),
        "touched": mask,
        "material": np.full((b, p), -1),
        "k": a["k_w_mk"],
        "rho": a["rho_kg_m3"],
        "c": a["c_j_kgk"],
        "effusivity": np.sqrt(a["k_w_mk"] * a["rho_kg_m3"] * a["c_j_kgk"]),
        "diffusivity": a["k_w_mk"] / (a["rho_kg_m3"] * a["c_j_kgk"]),
        "conductance": a["conductance_w_m2k"],
        "radius_mm": a["radius_mm"],
        "spreading": spreading,
        "object_c": object_c,
        "v0": ambient[:, None] + heater / loss - object_c,
        "onset": a["onset_s"],
        "release": a["onset_s"] + a["contact_s"],
        "heat_capacity": heat_capacity,
        "loss": loss,
        "heater": heater,
        "ambient": ambient,
    }


@dataclass(frozen=True)
class Touches:
    """Every quantity of ``B`` touches: ``params[name]`` (B, P) float64 (``ambient`` (B,)), the keys
    of :meth:`TouchGenerator.draw` (the physics reads ``touched``, ``heat_capacity``, ``loss``,
    ``heater``, ``ambient``, ``conductance``, ``effusivity``, ``spreading``, ``v0``, ``object_c``,
    ``onset``, ``release``; real-sensor scenes more)."""

    params: dict[str, np.ndarray]

    #: the arrays of :meth:`from_arrays` (a user's ``.npz``): each (B,) or one value
    FIELDS: ClassVar[dict[str, str]] = {
        "object_c": "the object's temperature (degC)",
        "material": "material names from synth/data/materials.toml (e.g. 'aluminium'), or the three below",
        "k_w_mk": "the object's conductivity (W/(m K)), instead of 'material'",
        "rho_kg_m3": "its density (kg/m^3), instead of 'material'",
        "c_j_kgk": "its specific heat (J/(kg K)), instead of 'material'",
        "conductance_w_m2k": "interface conductance (W/(m^2 K)), optional (default: the scene's geometric middle)",
        "radius_mm": "contact patch radius (mm), optional (default: the scene's middle)",
        "onset_s": "contact onset (s from the record's start), optional (default: the scene's middle)",
        "contact_s": "contact duration (s) before release, optional (default: the scene's middle)",
        "ambient_c": "ambient temperature (degC), optional (default: the scene's middle)",
        "touched": "(B, P) bool: the pixels in contact, optional (default: all)",
    }

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], config: ThermalConfig) -> Touches:
        """A stimulus from named arrays (:attr:`FIELDS`), validated; unset contact quantities take
        the middle of the scene's ranges."""
        cc = config.contact
        names = optional(arrays, "material")
        if names is not None:
            if any(k in arrays for k in ("k_w_mk", "rho_kg_m3", "c_j_kgk")):
                raise InputError("stimulus: give either 'material' or 'k_w_mk', 'rho_kg_m3', 'c_j_kgk', not both")
            if names.dtype.kind != "U":
                raise InputError(f"material: expected material names (strings), got {names.dtype}")
            found = [get_material(str(name)) for name in np.atleast_1d(names)]
            props = {
                "k_w_mk": np.array([m.k_w_mk for m in found]),
                "rho_kg_m3": np.array([m.rho_kg_m3 for m in found]),
                "c_j_kgk": np.array([m.c_j_kgk for m in found]),
            }
        else:
            props = {key: take(arrays, key) for key in ("k_w_mk", "rho_kg_m3", "c_j_kgk")}

        def given(name: str, default: float) -> Any:
            value = optional(arrays, name)
            return default if value is None else value

        return cls.from_objects(
            config,
            object_c=take(arrays, "object_c"),
            **props,
            conductance_w_m2k=given("conductance_w_m2k", float(np.sqrt(np.prod(cc.conductance_w_m2k)))),
            radius_mm=given("radius_mm", float(np.mean(cc.radius_mm))),
            onset_s=given("onset_s", float(np.mean(cc.onset_s))),
            contact_s=given("contact_s", float(np.mean(cc.contact_s))),
            ambient_c=optional(arrays, "ambient_c"),
            touched=optional(arrays, "touched"),
        )

    def __len__(self) -> int:
        return len(self.params["touched"])

    def __getitem__(self, name: str) -> np.ndarray:
        return self.params[name]

    def take(self, rows: slice) -> Touches:
        """The touches ``rows`` (a block of the batch)."""
        return Touches({k: v[rows] for k, v in self.params.items()})

    @classmethod
    def from_objects(
        cls,
        config: ThermalConfig,
        *,
        object_c: Any,
        k_w_mk: Any,
        rho_kg_m3: Any,
        c_j_kgk: Any,
        conductance_w_m2k: Any,
        radius_mm: Any,
        onset_s: Any,
        contact_s: Any,
        ambient_c: Any = None,
        touched: Any = None,
    ) -> Touches:
        """A user's touches of the scene's sensor, one object per touch over the pixels ``touched``
        (B, P) (default all), each argument (B,) or one value: the object's temperature (degC) and
        properties, the interface conductance, the contact radius (spreading, as the scene says),
        onset and duration (s). The sensor sits at the middle of the scene's ranges, every pixel
        alike; ``ambient_c`` defaults to the middle of the scene's range. Real-sensor scenes
        (lagging thermistors, controlled heaters, a passive channel) need drawn touches."""
        if config.dynamic:
            raise InputError(
                "thermal: this scene models a real sensor (lags, control, passive channel): "
                "user touches need a scene without them (e.g. 'thermal')"
            )
        sc = config.sensor
        p = config.n_pixels
        values = {
            "object_c": object_c,
            "k_w_mk": k_w_mk,
            "rho_kg_m3": rho_kg_m3,
            "c_j_kgk": c_j_kgk,
            "conductance_w_m2k": conductance_w_m2k,
            "radius_mm": radius_mm,
            "onset_s": onset_s,
            "contact_s": contact_s,
            "ambient_c": float(np.mean(sc.ambient_c)) if ambient_c is None else ambient_c,
        }
        arrays, b = _per_touch(values)
        a = {k: np.broadcast_to(v, (b,))[:, None] * np.ones((1, p)) for k, v in arrays.items()}
        mask = np.ones((b, p), bool) if touched is None else np.asarray(touched, dtype=bool)
        if mask.shape != (b, p):
            raise InputError(f"touched: expected shape ({b}, {p}), got {mask.shape}")
        ambient = np.broadcast_to(arrays["ambient_c"], (b,)).copy()
        return cls(_nominal_sensor_touch(config, a, mask, ambient))


class TouchGenerator(StimulusGenerator[Touches]):
    """Draws touches from the ``[thermal]`` table's distributions (see the module docstring)."""

    def __init__(self, config: ThermalConfig) -> None:
        self.config = config
        self.materials = config.material_list

    def _layout(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """Object index per pixel (n, P): -1 nothing, 0 first object, 1 second object.

        The grid is cut at a random row or column; object 0 covers one side, object 1 (with
        probability ``second_object``) the other, each as a band (like the seed's rods): the full
        side along the cut axis, a random contiguous span across it. Every touch has at least one
        pixel in contact.
        """
        rows, cols = self.config.grid
        out = np.full((n, rows, cols), -1, dtype=np.int8)
        u = rng.random((n, 7))
        for i in range(n):
            along_rows = u[i, 0] < 0.5 if rows > 1 and cols > 1 else rows > 1
            length, other = (rows, cols) if along_rows else (cols, rows)
            two = u[i, 1] < self.config.objects.second_object and length > 1
            cut = 1 + int(u[i, 2] * (length - 1)) if two else length
            sides = [(0, cut), (cut, length)] if two else [(0, length)]
            for obj, (a, b) in enumerate(sides):
                span = 1 + int(u[i, 3 + 2 * obj] * other)  # 1 .. other pixels across
                o0 = int(u[i, 4 + 2 * obj] * (other - span + 1))
                if along_rows:
                    out[i, a:b, o0 : o0 + span] = obj
                else:
                    out[i, o0 : o0 + span, a:b] = obj
        return out.reshape(n, rows * cols)

    def draw(self, n: int, rng: np.random.Generator) -> Touches:
        """Every random quantity of ``n`` touches (float64), the same whatever outputs are wanted."""
        cfg = self.config
        sc, cc, oc = cfg.sensor, cfg.contact, cfg.objects
        p = cfg.n_pixels

        def uni(rng_: tuple[float, float], shape: tuple[int, ...]) -> np.ndarray:
            return rng.uniform(rng_[0], rng_[1], size=shape)

        def log_uni(rng_: tuple[float, float], shape: tuple[int, ...]) -> np.ndarray:
            return np.exp(rng.uniform(np.log(rng_[0]), np.log(rng_[1]), size=shape))

        layout = self._layout(n, rng)
        # sensor: per touch, then a pixel spread (clipped at 3 s.d.: never non-physical)
        spread = np.clip(rng.standard_normal((n, p, 2)), -3, 3) * sc.pixel_spread
        heat_capacity = uni(sc.heat_capacity_j_m2k, (n, 1)) * (1 + spread[..., 0])
        loss = uni(sc.loss_w_m2k, (n, 1)) * (1 + spread[..., 1])
        heater = np.broadcast_to(uni(sc.heater_w_m2, (n, 1)), (n, p))
        ambient = uni(sc.ambient_c, (n,))
        # objects (2 per touch, the second unused when the layout has none)
        mat = rng.integers(0, len(self.materials), size=(n, 2))
        props = sample_properties(self.materials, mat, rng, oc.property_spread)
        offset = uni(oc.offset_k, (n, 2))
        h_obj = log_uni(cc.conductance_w_m2k, (n, 2))
        radius_mm = uni(cc.radius_mm, (n, 2))
        onset_touch = uni(cc.onset_s, (n,))
        onset_obj = np.maximum(onset_touch[:, None] + uni((-cc.onset_jitter_s, cc.onset_jitter_s), (n, 2)), 0.0)
        release_obj = onset_touch[:, None] + uni(cc.contact_s, (n, 1))
        h_pix = np.exp(cc.pixel_conductance_spread * np.clip(rng.standard_normal((n, p)), -3, 3))

        obj = np.maximum(layout, 0).astype(np.int64)
        touched = layout >= 0

        def per_pixel(values: np.ndarray) -> np.ndarray:
            return np.take_along_axis(values, obj, axis=1)

        k = per_pixel(props.k_w_mk)
        radius_m = per_pixel(radius_mm) * 1e-3
        spreading = spreading_conductance(k, radius_m) if cc.spreading else np.zeros_like(k)
        object_c = ambient[:, None] + per_pixel(offset)
        v0 = ambient[:, None] + heater / loss - object_c
        # drawn after the seed's quantities: the seed's scenes keep their streams
        extra = draw_dynamics(cfg, n, p, rng) if cfg.dynamic else {}
        return Touches(
            {
                **extra,
                "layout": layout,
                "touched": touched,
                "material": np.where(touched, per_pixel(mat), -1),
                "k": k,
                "rho": per_pixel(props.rho_kg_m3),
                "c": per_pixel(props.c_j_kgk),
                "effusivity": per_pixel(props.effusivity),
                "diffusivity": per_pixel(props.diffusivity_m2_s),
                "conductance": per_pixel(h_obj) * h_pix,
                "radius_mm": per_pixel(radius_mm),
                "spreading": spreading,
                "object_c": np.where(touched, object_c, ambient[:, None]),
                "v0": v0,
                "onset": np.where(touched, per_pixel(onset_obj), onset_touch[:, None]),
                "release": np.broadcast_to(release_obj, (n, p)).copy(),
                "heat_capacity": heat_capacity,
                "loss": loss,
                "heater": heater,
                "ambient": ambient,
            }
        )

    def truth_specs(self, wanted: tuple[str, ...]) -> dict[str, ArraySpec]:
        p = self.config.n_pixels
        specs: dict[str, ArraySpec] = {}
        if "latent" in wanted:
            for key, (dtype, doc) in _LATENTS.items():
                specs[key] = ArraySpec((p,), dtype, doc)
            if self.config.dynamic:
                for key, (dtype, doc) in _DYNAMIC_LATENTS.items():
                    specs[key] = ArraySpec((p,), dtype, doc)
        return specs

    def truth(self, stimulus: Touches, wanted: tuple[str, ...]) -> dict[str, np.ndarray]:
        out: dict[str, np.ndarray] = {}
        if "latent" not in wanted:
            return out
        d = stimulus.params
        touched = d["touched"]
        f32 = np.float32

        def masked(x: np.ndarray) -> np.ndarray:
            return np.where(touched, x, 0.0).astype(f32)

        family = np.array([FAMILIES.index(m.family) for m in self.materials], dtype=np.int8)
        out.update(
            latent_material=d["material"].astype(np.int16),
            latent_family=np.where(touched, family[np.maximum(d["material"], 0)], -1).astype(np.int8),
            latent_object=d["layout"].astype(np.int8),
            latent_k_w_mk=masked(d["k"]),
            latent_rho_kg_m3=masked(d["rho"]),
            latent_c_j_kgk=masked(d["c"]),
            latent_effusivity=masked(d["effusivity"]),
            latent_diffusivity_mm2_s=masked(d["diffusivity"] * 1e6),
            latent_conductance_w_m2k=masked(d["conductance"]),
            latent_radius_mm=masked(d["radius_mm"]),
            latent_spreading_w_m2k=masked(d["spreading"]),
            latent_object_c=d["object_c"].astype(f32),
            latent_v0_k=masked(d["v0"]),
            latent_onset_s=d["onset"].astype(f32),
            latent_release_s=d["release"].astype(f32),
            latent_heat_capacity_j_m2k=d["heat_capacity"].astype(f32),
            latent_loss_w_m2k=d["loss"].astype(f32),
            latent_heater_w_m2=d["heater"].astype(f32),
            latent_ambient_c=np.broadcast_to(d["ambient"][:, None], touched.shape).astype(f32),
        )
        if self.config.dynamic:
            klass = self.config.class_of_material[np.maximum(d["material"], 0)]
            out.update(
                latent_class=np.where(touched, klass, -1).astype(np.int16),
                latent_ramp_s=d["ramp"].astype(f32),
                latent_drift_k_s=d["drift"].astype(f32),
                latent_lag_s=(d["lag1"] + d["lag2"]).astype(f32),
            )
        return out
