"""Configuration of the FSR film (the ``[fsr]`` table of a scene)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from synth.config import param
from synth.errors import ConfigError

__all__ = [
    "N_SENSORS",
    "FilmConfig",
    "FsrConfig",
    "FsrElementConfig",
    "LayoutConfig",
    "ReadoutConfig",
    "StimulusConfig",
    "TransferConfig",
]

#: FSR discs in the film
N_SENSORS = 6


@dataclass(frozen=True)
class LayoutConfig:
    """Film and sensor geometry."""

    size_mm: float = param(80.0, lo=20.0, hi=500.0, unit="mm", doc="film side (square film)")
    thickness_mm: float = param(8.0, lo=1.0, hi=50.0, unit="mm", doc="film thickness (on a rigid base)")
    sensor_depth_mm: float = param(6.0, lo=0.5, hi=49.0, unit="mm", doc="depth of the sensor plane below the surface")
    side_mm: float = param(20.0, lo=5.0, hi=200.0, unit="mm", doc="side of each of the four small triangles")
    sensor_diameter_mm: float = param(5.0, lo=0.5, hi=30.0, unit="mm", doc="FSR active disc diameter (FSR400: 5)")
    youngs_modulus_mpa: float = param(5.0, lo=0.01, hi=1000.0, unit="MPa", doc="PDMS Young's modulus (paper: ~5)")
    poisson: float = param(0.49, lo=0.0, hi=0.5, doc="PDMS Poisson ratio")

    def __post_init__(self) -> None:
        if self.sensor_depth_mm >= self.thickness_mm:
            raise ConfigError(
                f"sensor_depth_mm: {self.sensor_depth_mm} mm must be less than thickness_mm ({self.thickness_mm} mm)"
            )
        # the big triangle (side 2 * side_mm) must fit inside the film with its discs
        height = 2.0 * self.side_mm * math.sqrt(3.0) / 2.0
        reach_y = 2.0 * height / 3.0 + self.sensor_diameter_mm / 2.0
        reach_x = self.side_mm + self.sensor_diameter_mm / 2.0
        if max(reach_x, reach_y) > self.size_mm / 2.0:
            raise ConfigError(f"side_mm: triangles of side {self.side_mm} mm do not fit on a {self.size_mm} mm film")
        if self.sensor_diameter_mm >= self.side_mm:
            raise ConfigError(
                f"sensor_diameter_mm: {self.sensor_diameter_mm} mm discs overlap at side {self.side_mm} mm"
            )


@dataclass(frozen=True)
class TransferConfig:
    """How surface pressure reaches the sensor discs (see the module docstring, stage 2)."""

    layer_gain: float = param(
        1.5,
        lo=0.1,
        hi=10.0,
        doc="finite-layer correction: factor on the half-space stress at the sensors' depth",
    )
    share_gain: float = param(
        10.0, lo=0.0, hi=50.0, doc="load sharing: weight of the wide term carried by the stiff discs"
    )
    share_length_mm: float = param(
        16.0,
        lo=1.0,
        hi=100.0,
        unit="mm",
        doc="load sharing: spread length (depth parameter of the wide term)",
    )


@dataclass(frozen=True)
class FsrElementConfig:
    """The FSR400's conductance law (datasheet)."""

    break_force_n: float = param(0.15, lo=0.0, hi=5.0, unit="N", doc="actuation (break) force (FSR400: 0.1-0.2 N)")
    break_width_n: float = param(0.01, lo=1e-4, hi=1.0, unit="N", doc="width of the logistic turn-on at the break")
    conductance_us_per_n: float = param(
        100.0, lo=0.1, hi=1e5, lo_open=True, unit="uS/N", doc="conductance per newton above the break (1/R)"
    )
    saturation_force_n: float = param(
        12.0, lo=0.1, hi=1000.0, unit="N", doc="soft saturation: conductance tends to c * F_sat"
    )
    leak_conductance_us: float = param(0.05, lo=0.0, hi=10.0, unit="uS", doc="unloaded conductance (> 10 MOhm)")

    def __post_init__(self) -> None:
        if self.break_width_n > max(self.break_force_n, 1e-3):
            raise ConfigError(
                f"break_width_n: {self.break_width_n} N is wider than the break force ({self.break_force_n} N)"
            )


@dataclass(frozen=True)
class ReadoutConfig:
    """Voltage divider and ADC."""

    supply_v: float = param(3.3, lo=0.5, hi=30.0, unit="V", doc="divider supply = ADC reference")
    divider_kohm: float = param(10.0, lo=0.01, hi=10000.0, unit="kOhm", doc="measuring resistor of the divider")
    adc_bits: int = param(10, lo=4, hi=10, doc="ADC resolution (at most 10 bits, as in the issue)")
    noise_lsb: float = param(0.7, lo=0.0, hi=100.0, unit="LSB", doc="rms ADC input noise (before quantisation)")


@dataclass(frozen=True)
class FilmConfig:
    """How films (the six sensors' gains) are drawn."""

    gain_spread: float = param(0.06, lo=0.0, hi=0.5, doc="part-to-part gain spread (datasheet +/-6 %)")
    repeatability: float = param(0.02, lo=0.0, hi=0.5, doc="per-press gain repeatability (datasheet +/-2 %)")
    distribution: Literal["uniform", "normal"] = param(
        "uniform", doc="uniform: anywhere in +/- the figure; normal: the figure is one sigma (3-sigma cut)"
    )
    frames_per_film: int = param(64, lo=1, hi=1_000_000, doc="frames simulated on each drawn film")
    gains: tuple[float, ...] | None = param(
        None, lo=0.05, hi=20.0, doc="one calibrated film's six gains (set by calibrate); None draws films"
    )

    def __post_init__(self) -> None:
        if self.gains is not None and len(self.gains) != N_SENSORS:
            raise ConfigError(f"gains: expected {N_SENSORS} values (one per sensor), got {len(self.gains)}")


@dataclass(frozen=True)
class StimulusConfig:
    """Round indenter tips pressed anywhere on the film, one contact per frame."""

    force_range_n: tuple[float, float] = param(
        (0.1, 10.0), lo=0.001, hi=100.0, lo_open=True, unit="N", ordered=True, doc="force range (log-uniform)"
    )
    tip_radii_mm: tuple[float, ...] = param(
        (2.0, 4.0, 8.0),
        lo=0.1,
        hi=100.0,
        lo_open=True,
        unit="mm",
        doc="spherical tip radii (one drawn per frame)",
    )
    no_contact_fraction: float = param(0.1, lo=0.0, hi=1.0, doc="fraction of frames without contact")
    inside_fraction: float = param(
        0.5, lo=0.0, hi=1.0, doc="fraction of contacts drawn inside the four triangles (the rest: whole film)"
    )
    edge_margin_mm: float = param(1.0, lo=0.0, hi=20.0, unit="mm", doc="contacts stay this far from the film's edge")
    second_press_fraction: float = param(
        0.0,
        lo=0.0,
        hi=1.0,
        omit_default=True,
        doc="fraction of contact frames with a second, simultaneous round press (not what the film's "
        "estimators assume: they should flag it)",
    )
    flat_fraction: float = param(
        0.0,
        lo=0.0,
        hi=1.0,
        omit_default=True,
        doc="fraction of contact frames pressed by a large flat indenter (uniform pressure on a disc) "
        "instead of a round tip",
    )
    flat_radius_mm: tuple[float, float] = param(
        (10.0, 20.0), lo=0.5, hi=40.0, unit="mm", ordered=True, omit_default=True, doc="flat indenter radius"
    )

    def __post_init__(self) -> None:
        if not self.tip_radii_mm:
            raise ConfigError("tip_radii_mm: at least one tip radius is needed")

    @property
    def unusual(self) -> bool:
        """Draws presses the one-round-press estimators do not model (two presses, flat indenters)."""
        return self.second_press_fraction > 0 or self.flat_fraction > 0


@dataclass(frozen=True)
class FsrConfig:
    """The ``[fsr]`` scene table."""

    layout: LayoutConfig = param(LayoutConfig(), doc="film and sensor geometry")
    transfer: TransferConfig = param(TransferConfig(), doc="load path from the surface to the discs")
    element: FsrElementConfig = param(FsrElementConfig(), doc="FSR conductance law")
    readout: ReadoutConfig = param(ReadoutConfig(), doc="voltage divider and ADC")
    film: FilmConfig = param(FilmConfig(), doc="gain spread and repeatability")
    stimulus: StimulusConfig = param(StimulusConfig(), doc="indenters, forces and positions")

    def __post_init__(self) -> None:
        half = self.layout.size_mm / 2.0 - self.stimulus.edge_margin_mm
        if half <= 0:
            raise ConfigError("stimulus.edge_margin_mm: leaves no room on the film")
