"""Configuration of the heated thermal fingertip (the ``[thermal]`` table of a scene)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np

from synth.config import param
from synth.errors import ConfigError
from synth.materials import Material, resolve_label, resolve_materials

__all__ = [
    "ContactConfig",
    "ObjectClass",
    "ObjectsConfig",
    "PassiveConfig",
    "ReadoutConfig",
    "SensorConfig",
    "ThermalConfig",
]


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
    # a real sensor (synth.sensors.thermal.touch): every field below is left out of a scene's plain
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
    (:mod:`synth.sensors.thermal.touch`). Disabled by default."""

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
        """Whether touches need the real-sensor model (:mod:`synth.sensors.thermal.touch`)."""
        return (
            self.sensor.dynamic
            or self.passive.enabled
            or max(self.contact.ramp_s) > 0
            or self.readout.timing_jitter_s > 0
        )
