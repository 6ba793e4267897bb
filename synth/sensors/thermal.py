"""Heated thermal fingertip: a 4 x 4 thermistor array touching semi-infinite objects.

Physics (seed 001, eq. 4-5; ``../shared/reference/physics.md`` section 3), per pixel:

* The pixel is a lumped heated body of heat capacity per area ``C = Mc`` (J/(m^2 K)) at excess
  temperature ``v(t)`` over the object's initial temperature. It is heated by ``Q`` (W/m^2) and
  loses heat to its surroundings (ambient / the finger's body) through ``G`` (W/(m^2 K)), so
  before contact it sits at its steady state ``T_amb + Q/G``; the object is at ``T_obj``, hence
  the initial sensor-object difference ``V0 = T_amb + Q/G - T_obj``. ``G = 0`` is the seed's model.
* On contact it feeds heat into the object through a series interface (contact) conductance
  ``H`` (W/(m^2 K)): rough surfaces trap air and lower ``H``.
* The object is a semi-infinite body of effusivity ``e = sqrt(k rho c)``. Its surface admittance
  in Laplace space is ``Z(s) = e sqrt(s) + k_s``: ``e sqrt(s)`` is the seed's 1-D body and
  ``k_s = 4 k / (pi a)`` the steady spreading conductance of a contact patch of radius ``a`` (a
  disk on a half-space). ``k_s = 0`` is exactly the seed's 1-D problem; with ``k_s > 0`` the model
  is exact for a spherical contact of radius ``k / k_s`` and interpolates the disk's short-time
  (1-D) and long-time (steady) limits, which is how the diffusivity enters at longer times
  (a modelling choice, documented here, not from the seed).

Solution. With ``q = sqrt(s)``, ``u = v - V0`` and ``S = Q + G (T_amb - T_obj) - G V0`` the net
heating at onset (0 for a sensor at its steady state; ``Q`` in the seed's model)::

    U(s) = N(q) / (q^2 D(q)),   N(q) = S (H + k_s + e q) - V0 H (e q + k_s),
    D(q) = C e q^3 + C (H + k_s) q^2 + e (G + H) q + G (H + k_s) + H k_s.

``D`` is a cubic with positive coefficients and ``a2 a1 - a3 a0 = C e H^2 > 0`` (Routh-Hurwitz),
so its roots ``p_i`` have negative real parts (they may be complex). Partial fractions in ``q``
and ``1/(sqrt(s) - p) <-> 1/sqrt(pi t) + p erfcx(-p sqrt(t))`` give, for simple roots,

    v(t) = V0 + sum_i  N(p_i) / D'(p_i) * phi(p_i, t),   phi(p, t) = (erfcx(-p sqrt t) - 1) / p,

where the ``1/sqrt(pi t)`` terms cancel exactly (``U = O(q^-4)``). ``Re(-p) >= 0`` keeps every
``erfcx`` argument in its bounded half plane, so the curve is finite for every ``t >= 0`` in
float32 and float64 (the seed's ``exp(h^2 a t) erfc(...)`` form overflows). ``phi`` uses its power
series near ``p sqrt(t) = 0`` (``phi(0, t) = 2 sqrt(t/pi)``: the seed's ``G = k_s = 0`` root at 0),
and a pair of nearly equal roots is split by a relative nudge of ``H`` of at most ~1e-5 (the
partial fractions of a double root are singular; the curve moves by less than that). With
``H -> inf``, ``G = k_s = 0`` the formula is the seed's eq. 5 at ``x = 0``.

After release (time ``t_r``) the pixel relaxes alone: ``C dv/dt = P - G v`` with
``P = S + G V0``; recovery to 90 % takes ``ln(10) C / G`` (the seed measured 18 s).

Readout: each thermistor reads ``T_obj + v`` (degrees C) plus Gaussian noise ``noise_k``, then an
ADC of step ``adc_step_k`` clipped to ``adc_range_c`` (:class:`Readout`; ``scene.noise = False``
gives the clean, unquantised curve). Pixels are independent (no lateral conduction between
thermistors: a simplification).

Each touch puts one or two objects on the grid (as in the seed's aluminium and wooden rods): each
object covers a rectangle of pixels, the rest touch nothing. Per object: material (uniform over the
scene's list) with properties drawn within their spread, temperature offset from ambient, contact
conductance (log-uniform, then a log-normal spread per pixel), contact radius, onset (the touch's
onset plus a small jitter) and release.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np
from scipy import linalg, special

from synth.config import param
from synth.errors import ConfigError, InputError
from synth.materials import FAMILIES, Material, resolve_label, resolve_materials, sample_properties
from synth.scene import Scene
from synth.sensors.base import ArraySpec

__all__ = [
    "CONFIG_CLASS",
    "DEFAULT_OUTPUTS",
    "OUTPUTS",
    "ContactConfig",
    "ContactModel",
    "ObjectClass",
    "ObjectsConfig",
    "PassiveConfig",
    "Readout",
    "ReadoutConfig",
    "SensorConfig",
    "ThermalConfig",
    "ThermalSimulator",
    "contact_excess",
    "make_simulator",
    "phi",
    "recovery_excess",
    "spreading_conductance",
    "touch_excess",
]


# -------------------------------------------------------------------------------------------------
# configuration


@dataclass(frozen=True)
class SensorConfig:
    """The heated sensor. Ranges are drawn uniformly per touch (unit-to-unit or day-to-day spread);
    ``pixel_spread`` adds a pixel-to-pixel spread of heat capacity and loss."""

    heat_capacity_j_m2k: tuple[float, float] = param(
        (1900.0, 2100.0), lo=1.0, hi=1e6, unit="J/(m^2 K)", ordered=True, doc="heat capacity per area Mc of a pixel"
    )
    loss_w_m2k: tuple[float, float] = param(
        (240.0, 260.0),
        lo=0.0,
        lo_open=True,
        hi=1e5,
        unit="W/(m^2 K)",
        ordered=True,
        doc="conductance from the heated pixel to its surroundings; recovery time constant is Mc / G",
    )
    heater_w_m2: tuple[float, float] = param(
        (4950.0, 5050.0),
        lo=0.0,
        lo_open=True,
        hi=1e6,
        unit="W/m^2",
        ordered=True,
        doc="heater output Q; the sensor's steady excess over ambient is Q / G (heater 'off': its power "
        "when it switches off)",
    )
    pixel_spread: float = param(0.02, lo=0.0, hi=0.3, doc="relative s.d. of heat capacity and loss per pixel")
    ambient_c: tuple[float, float] = param((18.0, 28.0), lo=-50.0, hi=100.0, unit="degC", ordered=True)
    # a real sensor (synth.sensors.thermal_touch): every field below is left out of a scene's plain
    # data while it holds its default, so the seed's scenes keep their digests
    lag_s: tuple[float, float] = param(
        (0.0, 0.0), lo=0.0, hi=100.0, unit="s", ordered=True, omit_default=True, doc="thermistor lag tau_1 (0: none)"
    )
    lag2_s: tuple[float, float] = param(
        (0.0, 0.0), lo=0.0, hi=100.0, unit="s", ordered=True, omit_default=True, doc="second thermistor lag tau_2"
    )
    heater: Literal["open", "constant", "held", "off", "step"] = param(
        "open",
        omit_default=True,
        doc="open: constant power Q, the sensor at ambient + Q/G before contact (the seed's); constant: held at "
        "set_point_c before contact, then the heater keeps its power; held: a PI controller holds the reading at "
        "set_point_c; off: held at set_point_c until heater_off_s after the onset, then switched off; step: its "
        "power changes by heater_step_w_m2 at heater_off_s (a rig that reacts to the press)",
    )
    heater_step_w_m2: tuple[float, float] = param(
        (0.0, 0.0), lo=-1e6, hi=1e6, unit="W/m^2", ordered=True, omit_default=True, doc="step: the power change"
    )
    set_point_c: tuple[float, float] = param(
        (30.0, 30.0),
        lo=-50.0,
        hi=200.0,
        unit="degC",
        ordered=True,
        omit_default=True,
        doc="held/off: reading before contact",
    )
    controller_kp: tuple[float, float] = param(
        (0.0, 0.0), lo=0.0, hi=1e7, unit="W/(m^2 K)", ordered=True, omit_default=True, doc="held: proportional gain"
    )
    controller_ki: tuple[float, float] = param(
        (0.0, 0.0), lo=0.0, hi=1e7, unit="W/(m^2 K s)", ordered=True, omit_default=True, doc="held: integral gain"
    )
    heater_off_s: tuple[float, float] = param(
        (0.0, 0.0), lo=-10.0, hi=100.0, unit="s", ordered=True, omit_default=True, doc="off: switch-off after the onset"
    )
    drift_k_s: tuple[float, float] = param(
        (0.0, 0.0),
        lo=-10.0,
        hi=10.0,
        unit="K/s",
        ordered=True,
        omit_default=True,
        doc="drift of the reading before contact (a heater still settling); it goes on as net heating",
    )

    def __post_init__(self) -> None:
        if self.heater == "held" and self.drift_k_s != (0.0, 0.0):
            raise ConfigError("sensor.drift_k_s: a held sensor rests at its set point before contact (use [0.0, 0.0])")
        if self.heater != "held" and (self.controller_kp != (0.0, 0.0) or self.controller_ki != (0.0, 0.0)):
            raise ConfigError(f"sensor.controller_kp/ki: the heater is {self.heater!r}; gains need heater = 'held'")

    @property
    def dynamic(self) -> bool:
        """Whether the heated channel needs the real-sensor model (lags, control, drift)."""
        return self.heater != "open" or max(self.lag_s) > 0 or max(self.lag2_s) > 0 or max(map(abs, self.drift_k_s)) > 0


@dataclass(frozen=True)
class PassiveConfig:
    """An unheated thermistor beside each heated pixel, touching the same object
    (:mod:`synth.sensors.thermal_touch`). Disabled by default."""

    enabled: bool = param(False, doc="simulate the passive channel (output 'passive')")
    heat_capacity_j_m2k: tuple[float, float] = param(
        (500.0, 500.0), lo=1.0, hi=1e6, unit="J/(m^2 K)", ordered=True, doc="heat capacity per area"
    )
    loss_w_m2k: tuple[float, float] = param(
        (20.0, 20.0), lo=0.0, hi=1e5, unit="W/(m^2 K)", ordered=True, doc="loss to the surroundings"
    )
    conductance_w_m2k: tuple[float, float] = param(
        (300.0, 300.0), lo=1.0, hi=1e9, unit="W/(m^2 K)", ordered=True, doc="contact conductance, log-uniform"
    )
    lag_s: tuple[float, float] = param((0.0, 0.0), lo=0.0, hi=100.0, unit="s", ordered=True, doc="lag tau_1")
    lag2_s: tuple[float, float] = param((0.0, 0.0), lo=0.0, hi=100.0, unit="s", ordered=True, doc="lag tau_2")
    offset_k: tuple[float, float] = param(
        (0.0, 0.0), lo=-50.0, hi=50.0, unit="K", ordered=True, doc="reading before contact minus ambient"
    )
    drift_k_s: tuple[float, float] = param(
        (0.0, 0.0), lo=-10.0, hi=10.0, unit="K/s", ordered=True, doc="drift before contact, whatever the object"
    )
    approach_per_s: tuple[float, float] = param(
        (0.0, 0.0),
        lo=0.0,
        hi=10.0,
        unit="1/s",
        ordered=True,
        doc="approaching the object already couples to it: a further drift of this rate times (object - reading)",
    )


@dataclass(frozen=True)
class ContactConfig:
    """How objects touch: interface conductance, contact patch, timing."""

    conductance_w_m2k: tuple[float, float] = param(
        (3000.0, 50000.0),
        lo=1.0,
        hi=1e9,
        unit="W/(m^2 K)",
        ordered=True,
        doc="series interface conductance H per object, log-uniform (rough surfaces: low)",
    )
    pixel_conductance_spread: float = param(0.2, lo=0.0, hi=2.0, doc="log-normal s.d. of H from pixel to pixel")
    radius_mm: tuple[float, float] = param(
        (3.0, 10.0), lo=0.1, hi=1000.0, unit="mm", ordered=True, doc="contact patch radius a per object"
    )
    spreading: bool = param(True, doc="add the finite patch's spreading conductance 4 k / (pi a)")
    onset_s: tuple[float, float] = param((2.3, 3.0), lo=0.0, hi=1e4, unit="s", ordered=True, doc="contact onset")
    onset_jitter_s: float = param(0.02, lo=0.0, hi=10.0, unit="s", doc="per-object onset jitter (uniform +-)")
    contact_s: tuple[float, float] = param(
        (2.2, 3.0), lo=0.0, lo_open=True, hi=1e5, unit="s", ordered=True, doc="contact duration before release"
    )
    ramp_s: tuple[float, float] = param(
        (0.0, 0.0),
        lo=0.0,
        hi=100.0,
        unit="s",
        ordered=True,
        omit_default=True,
        doc="time the contact takes to build up",
    )


@dataclass(frozen=True)
class ObjectClass:
    """A user class: a name and the library materials (or families) it stands for."""

    name: str = param("", doc="class name (a touch label)")
    materials: tuple[str, ...] = param((), doc="materials or families of the class")

    def __post_init__(self) -> None:
        if not self.name:
            raise ConfigError("classes: every class needs a name")
        if not self.materials:
            raise ConfigError(f"classes: class {self.name!r} lists no materials")
        for entry in self.materials:
            resolve_label(entry)  # raises ConfigError naming the unknown entry and what is accepted


@dataclass(frozen=True)
class ObjectsConfig:
    """What is touched."""

    materials: tuple[str, ...] = param((), doc="material names from synth.materials; empty = whole library")
    classes: tuple[ObjectClass, ...] = param(
        (), omit_default=True, doc="user classes; when given they are what is classified (materials stays empty)"
    )
    offset_k: tuple[float, float] = param(
        (-4.0, 4.0), lo=-100.0, hi=100.0, unit="K", ordered=True, doc="object temperature minus ambient"
    )
    second_object: float = param(0.5, lo=0.0, hi=1.0, doc="probability of a second object on the grid")
    property_spread: float = param(1.0, lo=0.0, hi=1.0, doc="scale of the library's property spreads")

    def __post_init__(self) -> None:
        resolve_materials(self.materials)  # raises ConfigError naming an unknown material
        if self.classes and self.materials:
            raise ConfigError("objects: give either materials or classes, not both")
        names = [c.name for c in self.classes]
        if len(set(names)) != len(names):
            raise ConfigError(f"objects.classes: a class is listed twice ({', '.join(names)})")
        members = [m.name for c in self.classes for m in _class_materials(c)]
        if len(set(members)) != len(members):
            raise ConfigError("objects.classes: a material belongs to two classes")


def _class_materials(cls: ObjectClass) -> tuple[Material, ...]:
    out: list[Material] = []
    for entry in cls.materials:
        for m in resolve_label(entry):
            if m not in out:
                out.append(m)
    return tuple(out)


@dataclass(frozen=True)
class ReadoutConfig:
    """Sampling, thermistor noise and ADC."""

    sampling_hz: float = param(50.0, lo=0.1, hi=10000.0, unit="Hz")
    duration_s: float = param(6.5, lo=0.01, hi=1e5, unit="s", doc="record length")
    noise_k: float = param(0.01, lo=0.0, hi=10.0, unit="K", doc="thermistor noise s.d.")
    adc_step_k: float = param(0.01, lo=0.0, hi=10.0, unit="K", doc="ADC step (0 = no quantisation)")
    adc_range_c: tuple[float, float] = param((0.0, 100.0), lo=-273.0, hi=1000.0, unit="degC", ordered=True)
    timing_jitter_s: float = param(
        0.0, lo=0.0, hi=1.0, unit="s", omit_default=True, doc="s.d. of the recorder's time-stamp jitter"
    )

    @property
    def n_samples(self) -> int:
        return max(1, round(self.duration_s * self.sampling_hz))


@dataclass(frozen=True)
class ThermalConfig:
    grid: tuple[int, int] = param((4, 4), lo=1, hi=64, doc="thermistor rows, columns")
    window_s: float = param(2.5, lo=0.01, hi=1e4, unit="s", doc="classifier input window (ends at 'now')")
    sensor: SensorConfig = param(SensorConfig())
    contact: ContactConfig = param(ContactConfig())
    objects: ObjectsConfig = param(ObjectsConfig())
    readout: ReadoutConfig = param(ReadoutConfig())
    passive: PassiveConfig = param(PassiveConfig(), omit_default=True)
    channels: tuple[Literal["heated", "passive"], ...] = param(
        ("heated",), omit_default=True, doc="the channels a classifier reads, in this order"
    )

    def __post_init__(self) -> None:
        if not self.channels or self.channels[0] != "heated" or len(set(self.channels)) != len(self.channels):
            raise ConfigError(f"channels: {list(self.channels)} must start with 'heated' and name each channel once")
        if "passive" in self.channels and not self.passive.enabled:
            raise ConfigError("channels: 'passive' needs passive.enabled = true")
        if self.window_s > self.readout.duration_s:
            raise ConfigError(
                f"window_s: {self.window_s} s is longer than readout.duration_s ({self.readout.duration_s} s)"
            )
        if self.contact.onset_s[1] >= self.readout.duration_s:
            raise ConfigError(
                f"contact.onset_s: onsets up to {self.contact.onset_s[1]} s fall outside the "
                f"{self.readout.duration_s} s record"
            )
        lo, hi = self.readout.adc_range_c
        if hi <= lo:
            raise ConfigError(f"readout.adc_range_c: empty range {[lo, hi]}")
        if self.dynamic and self.contact.onset_s[0] + self.contact.contact_s[0] < self.readout.duration_s:
            raise ConfigError(
                "contact.contact_s: a real-sensor scene (lags, heater control, drift, contact ramp, passive channel "
                "or jitter) holds the contact to the end of the record: contact_s must reach readout.duration_s "
                f"from the earliest onset ({self.contact.onset_s[0]} + {self.contact.contact_s[0]} < "
                f"{self.readout.duration_s} s)"
            )

    @property
    def n_pixels(self) -> int:
        return self.grid[0] * self.grid[1]

    @property
    def window_samples(self) -> int:
        return max(2, round(self.window_s * self.readout.sampling_hz))

    @cached_property
    def material_list(self) -> tuple[Material, ...]:
        if self.objects.classes:
            return tuple(m for c in self.objects.classes for m in _class_materials(c))
        return resolve_materials(self.objects.materials)

    @cached_property
    def class_names(self) -> tuple[str, ...]:
        """What is classified: the user's classes, else one class per material."""
        if self.objects.classes:
            return tuple(c.name for c in self.objects.classes)
        return tuple(m.name for m in self.material_list)

    @cached_property
    def class_of_material(self) -> np.ndarray:
        """Class index of every entry of :attr:`material_list`."""
        if not self.objects.classes:
            return np.arange(len(self.material_list))
        return np.array([k for k, c in enumerate(self.objects.classes) for _ in _class_materials(c)])

    @property
    def dynamic(self) -> bool:
        """Whether touches need the real-sensor model (:mod:`synth.sensors.thermal_touch`)."""
        return (
            self.sensor.dynamic
            or self.passive.enabled
            or max(self.contact.ramp_s) > 0
            or self.readout.timing_jitter_s > 0
        )


CONFIG_CLASS = ThermalConfig
OUTPUTS: dict[str, str] = {
    "readings": "thermistor temperatures (degC) of every pixel over the record: (P, R), pixels row-major",
    "passive": "the passive (unheated) thermistor beside every pixel (degC): (P, R); needs passive.enabled",
    "latent": "per-pixel truth: material, its properties, contact, temperatures, onset, release, sensor",
}
DEFAULT_OUTPUTS = ("readings", "latent")


# -------------------------------------------------------------------------------------------------
# physics: the analytic contact solution

_SQRT_PI = math.sqrt(math.pi)
#: power-series coefficients of g(y) = (1 - erfcx(y)) / y = sum_n (-1)^(n+1) y^(n-1) / Gamma(n/2 + 1)
_G_SERIES = np.array([(-1.0) ** (n + 1) / math.gamma(n / 2 + 1) for n in range(1, 19)])
#: |y| below which the series is used (18 terms: truncation < 1e-19 relative there)
_SERIES_RADIUS = 0.1


def phi(p: np.ndarray, t: np.ndarray, dtype: type = np.float64) -> np.ndarray:
    """``(erfcx(-p sqrt t) - 1) / p`` for complex ``p`` with ``Re p <= 0`` and ``t >= 0``.

    Computed as ``sqrt(t) g(y)``, ``y = -p sqrt(t)``, ``g(y) = (1 - erfcx(y)) / y``, with ``g``'s
    power series for ``|y| < 0.1`` (the direct quotient cancels there) and ``g(0) = 2/sqrt(pi)``.
    ``dtype`` float32 evaluates in complex64.
    """
    ctype = np.complex64 if np.dtype(dtype) == np.float32 else np.complex128
    rtype = np.float32 if ctype == np.complex64 else np.float64
    root_t = np.sqrt(np.maximum(np.asarray(t, dtype=rtype), 0))
    y = np.asarray(p, dtype=ctype) * (-root_t)
    small = np.abs(y) < _SERIES_RADIUS
    # the quotient only where |y| >= 0.1: no division by (near) zero
    y_safe = np.where(small, ctype(1.0), y)
    direct = (1 - special.erfcx(y_safe)) / y_safe
    y_small = np.where(small, y, ctype(0.0))  # the series only where it converges fast
    series = np.zeros_like(y)
    for coef in _G_SERIES[::-1]:  # Horner
        series = series * y_small + ctype(coef)
    g = np.where(small, series, direct)
    return (root_t * g).astype(ctype)


def spreading_conductance(k_w_mk: float | np.ndarray, radius_m: float | np.ndarray) -> np.ndarray:
    """Steady spreading conductance per area of a disk of radius ``a`` on a half-space: ``4 k/(pi a)``."""
    return 4.0 * np.asarray(k_w_mk, dtype=np.float64) / (np.pi * np.asarray(radius_m, dtype=np.float64))


def _cubic(c: np.ndarray, g: np.ndarray, h: np.ndarray, e: np.ndarray, ks: np.ndarray) -> np.ndarray:
    """Coefficients (..., 4) of D(q), highest power first."""
    return np.stack([c * e, c * (h + ks), e * (g + h), g * (h + ks) + h * ks], axis=-1)


def _roots(coef: np.ndarray) -> np.ndarray:
    """Roots (..., 3) of the cubics ``coef`` (..., 4): companion-matrix eigenvalues, one Newton step."""
    a = coef[..., 1:] / coef[..., :1]  # a3 = C e > 0
    comp = np.zeros((*a.shape[:-1], 3, 3))
    comp[..., 0, :] = -a
    comp[..., 1, 0] = 1.0
    comp[..., 2, 1] = 1.0
    r = np.linalg.eigvals(comp).astype(np.complex128)
    for _ in range(2):  # polish: the eigen-solver's error is relative to the largest root
        f = ((r + a[..., :1]) * r + a[..., 1:2]) * r + a[..., 2:3]
        df = (3 * r + 2 * a[..., :1]) * r + a[..., 1:2]
        ok = np.abs(df) > 0  # a double root: keep it as it is (handled by the nudge)
        r = np.where(ok, r - f / np.where(ok, df, 1.0), r)
    return r


def _min_gap(r: np.ndarray) -> np.ndarray:
    """Smallest pairwise root distance relative to the larger of the two roots (0 for a double root)."""
    gaps = []
    for i, j in ((0, 1), (0, 2), (1, 2)):
        scale = np.maximum(np.maximum(np.abs(r[..., i]), np.abs(r[..., j])), 1e-300)  # avoids 0/0
        gaps.append(np.abs(r[..., i] - r[..., j]) / scale)
    return np.minimum(np.minimum(gaps[0], gaps[1]), gaps[2])


@dataclass(frozen=True)
class ContactModel:
    """One heated pixel touching one object: parameters broadcast to a common batch shape.

    ``heat_capacity`` C (J/(m^2 K)), ``loss`` G (W/(m^2 K), >= 0), ``conductance`` H (W/(m^2 K), > 0),
    ``effusivity`` e (W s^0.5/(m^2 K), > 0), ``spreading`` k_s (W/(m^2 K), >= 0), ``v0`` the initial
    sensor-object difference (K), ``heating`` S the net heating at onset (W/m^2; 0 at steady state).
    """

    heat_capacity: np.ndarray
    loss: np.ndarray
    conductance: np.ndarray
    effusivity: np.ndarray
    spreading: np.ndarray
    v0: np.ndarray
    heating: np.ndarray

    @classmethod
    def create(
        cls,
        heat_capacity: float | np.ndarray,
        loss: float | np.ndarray,
        conductance: float | np.ndarray,
        effusivity: float | np.ndarray,
        spreading: float | np.ndarray = 0.0,
        v0: float | np.ndarray = 1.0,
        heating: float | np.ndarray = 0.0,
    ) -> ContactModel:
        arrays = np.broadcast_arrays(
            *(
                np.asarray(x, dtype=np.float64)
                for x in (heat_capacity, loss, conductance, effusivity, spreading, v0, heating)
            )
        )
        c, g, h, e, ks, v0_, s = (np.array(a) for a in arrays)
        names = ("heat_capacity", "loss", "conductance", "effusivity", "spreading", "v0", "heating")
        for name, arr in zip(names, (c, g, h, e, ks, v0_, s), strict=True):
            if not np.isfinite(arr).all():
                raise InputError(f"{name}: must be finite")
        for name, arr in (("heat_capacity", c), ("conductance", h), ("effusivity", e)):
            if (arr <= 0).any():
                raise InputError(f"{name}: must be > 0")
        for name, arr in (("loss", g), ("spreading", ks)):
            if (arr < 0).any():
                raise InputError(f"{name}: must be >= 0")
        return cls(c, g, h, e, ks, v0_, s)

    @cached_property
    def poles(self) -> tuple[np.ndarray, np.ndarray]:
        """Roots ``p`` (..., 3) of D and the weights ``N(p) / D'(p)`` (..., 3), complex128.

        Nearly equal roots (relative gap < 1e-3) are split by nudging H up by 1e-6, 1e-5, ... relative
        (a double root splits like the square root of the nudge).
        """
        c, g, e, ks, v0, s = self.heat_capacity, self.loss, self.effusivity, self.spreading, self.v0, self.heating
        h = self.conductance.copy()
        r = _roots(_cubic(c, g, h, e, ks))
        for nudge in (1e-6, 1e-5, 1e-4):
            close = _min_gap(r) < 1e-3
            if not close.any():
                break
            h = np.where(close, self.conductance * (1 + nudge), h)
            r = np.where(close[..., None], _roots(_cubic(c, g, h, e, ks)), r)
        coef = _cubic(c, g, h, e, ks)[..., None, :]
        num = s[..., None] * (h[..., None] + ks[..., None] + e[..., None] * r) - v0[..., None] * h[..., None] * (
            e[..., None] * r + ks[..., None]
        )
        dden = (3 * coef[..., 0] * r + 2 * coef[..., 1]) * r + coef[..., 2]
        return r, num / dden

    def excess(self, t: np.ndarray, dtype: type = np.float64) -> np.ndarray:
        """Sensor excess temperature ``v`` over the object's initial temperature, ``t`` seconds after
        onset (``t`` broadcasts against the batch shape with one trailing time axis: shape (..., T)).
        ``t < 0`` gives ``V0``."""
        r, w = self.poles
        ctype = np.complex64 if np.dtype(dtype) == np.float32 else np.complex128
        tt = np.asarray(t, dtype=np.float64)[..., None]  # (..., T, 1) against (..., 1, 3)
        terms = w[..., None, :].astype(ctype) * phi(r[..., None, :], tt, dtype)
        u = np.real(terms.sum(axis=-1))
        out = self.v0[..., None].astype(dtype) + u.astype(dtype)
        return np.asarray(np.where(tt[..., 0] < 0, self.v0[..., None], out), dtype=dtype)

    def excess_pairs(self, index: np.ndarray, t: np.ndarray, dtype: type = np.float64) -> np.ndarray:
        """Excess of batch member ``index[n]`` (flat index into the batch) at time ``t[n]`` after onset,
        for flat arrays of pairs: the sparse counterpart of :meth:`excess` (only the times needed)."""
        r, w = self.poles
        ctype = np.complex64 if np.dtype(dtype) == np.float32 else np.complex128
        flat_r = r.reshape(-1, 3)[index]
        flat_w = w.reshape(-1, 3)[index].astype(ctype)
        tt = np.asarray(t, dtype=np.float64)[:, None]
        u = np.real((flat_w * phi(flat_r, tt, dtype)).sum(axis=-1))
        v0 = self.v0.reshape(-1)[index]
        return np.asarray(np.where(tt[:, 0] < 0, v0, v0 + u), dtype=dtype)


def contact_excess(
    t: np.ndarray,
    heat_capacity: float | np.ndarray,
    loss: float | np.ndarray,
    conductance: float | np.ndarray,
    effusivity: float | np.ndarray,
    spreading: float | np.ndarray = 0.0,
    v0: float | np.ndarray = 1.0,
    heating: float | np.ndarray = 0.0,
    dtype: type = np.float64,
) -> np.ndarray:
    """Convenience wrapper: :meth:`ContactModel.excess` for scalar or batch parameters.

    ``t`` (T,) or (..., T) seconds after onset; returns (..., T) in ``dtype``.
    """
    model = ContactModel.create(heat_capacity, loss, conductance, effusivity, spreading, v0, heating)
    return model.excess(t, dtype)


def recovery_excess(
    dt: np.ndarray, v_release: np.ndarray, source: np.ndarray, heat_capacity: np.ndarray, loss: np.ndarray
) -> np.ndarray:
    """Pixel excess ``dt >= 0`` seconds after release: ``C dv/dt = P - G v``, ``v(0) = v_release``.

    ``v = v_r + (P - G v_r) dt phi1(G dt / C) / C`` with ``phi1(x) = (1 - exp(-x)) / x`` (``phi1(0) = 1``),
    stable for every ``G >= 0``. Arguments broadcast.
    """
    dt = np.maximum(np.asarray(dt, dtype=np.float64), 0.0)
    x = np.asarray(loss, dtype=np.float64) * dt / heat_capacity
    # phi1 via expm1 (no cancellation for small x); x = 0 handled by its limit 1
    x_safe = np.where(x > 1e-12, x, 1.0)
    phi1 = np.where(x > 1e-12, -np.expm1(-x_safe) / x_safe, 1.0 - x / 2)
    return v_release + (source - loss * v_release) * dt * phi1 / heat_capacity


def touch_excess(
    t: np.ndarray,
    model: ContactModel,
    onset: np.ndarray,
    release: np.ndarray,
    dtype: type = np.float64,
) -> np.ndarray:
    """Whole-record excess (..., T) at absolute times ``t`` (T,): ``V0`` before ``onset`` (a sensor at
    its steady state, ``S = 0``, or the ``S`` trend for ``S != 0`` is not modelled before contact),
    the contact solution until ``release``, then the lone pixel's recovery."""
    onset = np.asarray(onset, dtype=np.float64)[..., None]
    release = np.maximum(np.asarray(release, dtype=np.float64)[..., None], onset)
    t = np.asarray(t, dtype=np.float64)
    during = model.excess(np.minimum(t, release) - onset, np.float64)
    v_rel = model.excess(release - onset, np.float64)
    source = model.heating[..., None] + model.loss[..., None] * model.v0[..., None]
    after = recovery_excess(t - release, v_rel, source, model.heat_capacity[..., None], model.loss[..., None])
    return np.where(t >= release, after, during).astype(dtype)


def numerical_excess(
    t: np.ndarray,
    heat_capacity: float,
    loss: float,
    conductance: float,
    k_w_mk: float,
    diffusivity_m2_s: float,
    spreading: float = 0.0,
    v0: float = 1.0,
    heating: float = 0.0,
    cells: int = 400,
) -> np.ndarray:
    """Independent numerical solution of the same problem (a check of the analytic formula).

    Finite volumes in space on a geometrically graded grid; exact in time (eigen-decomposition of
    the symmetrised linear system, so no time-stepping error). ``spreading = 0`` solves the seed's
    1-D slab ``u_t = alpha u_xx``; ``spreading > 0`` solves a spherical cavity of radius
    ``a = k / spreading`` in an infinite body (``u_t = alpha (u_rr + 2 u_r / r)``), whose surface
    admittance is exactly ``e sqrt(s) + k / a``. The sensor node obeys
    ``C v' = S + G V0 - G v - H (v - u_surface)``. Returns ``v`` at the times ``t`` (s, > 0).
    """
    t = np.asarray(t, dtype=np.float64)
    alpha = diffusivity_m2_s
    t_min, t_max = float(t.min()), float(t.max())
    # grid: first cell resolves the shortest diffusion length, the body reaches 12 of the longest
    first = min(np.sqrt(alpha * t_min) / 40, 0.1 * k_w_mk / max(conductance, 1e-300) + 1e-12)
    length = 12 * np.sqrt(alpha * t_max)
    ratio = (length / first) ** (1.0 / cells)  # geometric widths summing to about ``length``
    widths = first * ratio ** np.arange(cells)
    faces = np.concatenate([[0.0], np.cumsum(widths)])
    centres = 0.5 * (faces[1:] + faces[:-1])
    if spreading > 0:
        a = k_w_mk / spreading
        r_faces, r_centres = a + faces, a + centres
        area = (r_faces / a) ** 2  # face area per unit contact area
        volume = (r_faces[1:] ** 3 - r_faces[:-1] ** 3) / (3 * a**2)
    else:
        area = np.ones_like(faces)
        volume = widths.copy()
        r_centres = centres
    rho_c = k_w_mk / alpha
    cap = np.concatenate([[heat_capacity], rho_c * volume])
    # conductances of the chain: sensor -> first cell centre (the interface conductance in series
    # with half a cell of body), then cell centre to cell centre; the far end is held at 0
    g0 = 1.0 / (1.0 / conductance + widths[0] / (2 * k_w_mk))
    links = np.concatenate([[g0], k_w_mk * area[1:cells] / np.diff(r_centres)])
    diag = np.zeros(cells + 1)
    diag[:-1] -= links
    diag[1:] -= links
    diag[0] -= loss
    # C y' = K y + b with b = (S + G V0) e_0, y(0) = V0 e_0. K is tridiagonal and symmetric: with
    # y = M^-1/2 z it becomes z' = A z + M^-1/2 b, A = M^-1/2 K M^-1/2 symmetric tridiagonal
    m = 1.0 / np.sqrt(cap)
    lam, vec = linalg.eigh_tridiagonal(diag * m * m, links * m[:-1] * m[1:])
    first = vec[0]  # only the sensor node is needed: y0 and b live on node 0
    z0 = first * v0 / m[0]
    bz = first * (heating + loss * v0) * m[0]
    lt = lam[None, :] * t[:, None]
    # per mode: z(t) = z0 e^(lam t) + bz (e^(lam t) - 1) / lam; lam < 0 (the held far end makes K
    # negative definite), expm1 keeps small lam t accurate
    growth = np.expm1(lt) / np.where(lam == 0, 1.0, lam)[None, :]
    z = z0[None, :] * np.exp(lt) + bz[None, :] * growth
    return (z * first[None, :]).sum(axis=1) * m[0]


# -------------------------------------------------------------------------------------------------
# readout


class Readout:
    """Thermistor noise and ADC: separate from the physics so tests can switch them off."""

    def __init__(self, config: ReadoutConfig) -> None:
        self.config = config

    def noise(self, clean: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        out = rng.standard_normal(clean.shape)
        out *= self.config.noise_k  # in place: the values of clean + noise_k * z, one temporary less
        out += clean
        return out

    def adc(self, temperature: np.ndarray) -> np.ndarray:
        lo, hi = self.config.adc_range_c
        step = self.config.adc_step_k
        if step <= 0:
            return np.clip(temperature, lo, hi)
        out = temperature / step
        np.round(out, out=out)
        out *= step
        return np.clip(out, lo, hi, out=out)

    def __call__(self, clean: np.ndarray, rng: np.random.Generator, noise: bool = True) -> np.ndarray:
        """Noisy, quantised readings (``noise=False``: the clean curve, unchanged)."""
        if not noise:
            return clean
        return self.adc(self.noise(clean, rng))


# -------------------------------------------------------------------------------------------------
# simulator

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


#: samples (touches x pixels x record) per block of :meth:`ThermalSimulator._readings`
_READOUT_BLOCK = 320_000


class ThermalSimulator:
    """Draws touches from the scene and computes the wanted outputs (float64 inside, float32 out).

    ``reference=True`` evaluates the contact solution on every sample of the record
    (:func:`touch_excess`); the default computes only the samples that need it
    (:func:`synth.sensors.thermal_fast.record_excess`, the same curve to rounding, ~10x faster).
    """

    def __init__(self, scene: Scene, reference: bool = False) -> None:
        self.scene = scene
        self.reference = reference
        self.config: ThermalConfig = scene.sensor
        self.readout = Readout(self.config.readout)
        self.materials = self.config.material_list
        r = self.config.readout
        self.time_s = np.arange(r.n_samples) / r.sampling_hz

    def output_specs(self) -> dict[str, ArraySpec]:
        p, r = self.config.n_pixels, self.config.readout.n_samples
        specs: dict[str, ArraySpec] = {}
        if self.scene.wants("readings"):
            specs["readings"] = ArraySpec((p, r), "float32", OUTPUTS["readings"])
        if self.scene.wants("passive"):
            if not self.config.passive.enabled:
                raise ConfigError("outputs: 'passive' needs [thermal.passive] enabled = true")
            specs["passive"] = ArraySpec((p, r), "float32", OUTPUTS["passive"])
        if self.scene.wants("latent"):
            for key, (dtype, doc) in _LATENTS.items():
                specs[key] = ArraySpec((p,), dtype, doc)
            if self.config.dynamic:
                for key, (dtype, doc) in _DYNAMIC_LATENTS.items():
                    specs[key] = ArraySpec((p,), dtype, doc)
        return specs

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

    def draw(self, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
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
        extra = {}
        if cfg.dynamic:  # drawn after the seed's quantities: the seed's scenes keep their streams
            from synth.sensors.thermal_touch import draw_dynamics

            extra = draw_dynamics(cfg, n, p, rng)
        return {
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

    def clean_readings(self, d: dict[str, np.ndarray]) -> np.ndarray:
        """Noise-free temperatures (n, P, R) in degC, float64."""
        n, p = d["touched"].shape
        out = np.empty((n, p, len(self.time_s)))
        # pixels touching nothing sit at their steady state T_amb + Q/G
        steady = d["ambient"][:, None] + d["heater"] / d["loss"]
        out[:] = steady[..., None]
        sel = d["touched"]
        if sel.any():
            model = ContactModel.create(
                d["heat_capacity"][sel],
                d["loss"][sel],
                d["conductance"][sel],
                d["effusivity"][sel],
                d["spreading"][sel],
                d["v0"][sel],
                0.0,
            )
            if self.reference:
                v = touch_excess(self.time_s, model, d["onset"][sel], d["release"][sel])
            else:
                from synth.sensors.thermal_fast import record_excess

                v = record_excess(self.time_s, model, d["onset"][sel], d["release"][sel])
            out[sel] = d["object_c"][sel][:, None] + v
        return out

    def _readings(self, d: dict[str, np.ndarray], rng: np.random.Generator) -> np.ndarray:
        """Noisy float32 readings (n, P, R), a few touches at a time (the reference path: all at once).
        The noise of consecutive blocks is the same stream as one draw for all: same bytes."""
        if self.reference:
            return self.readout(self.clean_readings(d), rng, self.scene.noise).astype(np.float32)
        n, p = d["touched"].shape
        out = np.empty((n, p, len(self.time_s)), dtype=np.float32)
        # blocks of ~32 touches keep the (touches, P, R) float64 temporaries in cache
        block = max(1, _READOUT_BLOCK // max(1, p * len(self.time_s)))
        for start in range(0, n, block):
            part = {k: v[start : start + block] for k, v in d.items()}
            out[start : start + block] = self.readout(self.clean_readings(part), rng, self.scene.noise)
        return out

    def simulate(self, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        d = self.draw(n, rng)
        out: dict[str, np.ndarray] = {}
        if self.config.dynamic:
            from synth.sensors.thermal_touch import clean_channels, jitter

            heated, passive = clean_channels(self.config, self.time_s, d)
            sigma = self.config.readout.timing_jitter_s if self.scene.noise else 0.0
            if self.scene.wants("readings"):
                out["readings"] = self.readout(jitter(heated, self.time_s, sigma, rng), rng, self.scene.noise).astype(
                    np.float32
                )
            if self.scene.wants("passive") and passive is not None:
                out["passive"] = self.readout(jitter(passive, self.time_s, sigma, rng), rng, self.scene.noise).astype(
                    np.float32
                )
        elif self.scene.wants("readings"):
            out["readings"] = self._readings(d, rng)
        if self.scene.wants("latent"):
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


def make_simulator(scene: Scene, reference: bool = False) -> ThermalSimulator:
    """The scene's simulator; ``reference``: the whole-record path (see :class:`ThermalSimulator`)."""
    return ThermalSimulator(scene, reference)
