"""Configuration of the capacitive pressure array (the ``[capacitive]`` table of a scene).

The seed's tactile half (seed 001; ``../shared/reference/physics.md`` section 4): an ``N x M`` array
of parallel-plate cells at ``pitch_mm``, a moulded silicone dielectric of round tabs on a backing,
an elastic cover on top, read by amplitude modulation ``V = V_in C_cell / C_fb``. The physics and
the meaning of every value are documented in :mod:`synth.sensors.capacitive.physics`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from synth.config import param
from synth.errors import ConfigError
from synth.sensors.strips.config import StimulusKind
from synth.stimuli import KINDS

__all__ = [
    "ArrayGeometry",
    "CalibrationTable",
    "CapacitiveConfig",
    "Cover",
    "Device",
    "Dielectric",
    "Hysteresis",
    "PressStimuli",
    "Readout",
]

#: grams-force to newtons (the seed states its range in grams)
G_TO_N = 9.80665e-3


@dataclass(frozen=True)
class ArrayGeometry:
    """Cell ``(i, j)`` is the ``pitch x pitch`` square whose centre is ``((j + 0.5) p, (i + 0.5) p)``
    from the array's corner (x along columns, y along rows); its plates overlap over ``plate_mm``
    squared. The surface pressure and every image output live on a fine lattice of
    ``samples_per_pitch`` cells per pitch (the estimators' output resolution: 2x-4x the taxels)."""

    n_rows: int = param(8, lo=1, hi=64, doc="rows of cells")
    n_cols: int = param(8, lo=1, hi=64, doc="columns of cells")
    pitch_mm: float = param(1.8, lo=0.2, hi=20.0, unit="mm", doc="cell centre to centre")
    plate_mm: float = param(1.6, lo=0.05, hi=20.0, unit="mm", doc="width of the row and column traces")
    samples_per_pitch: int = param(4, lo=2, hi=8, doc="fine-lattice samples per pitch (image outputs)")
    pad_mm: float = param(2.0, lo=0.0, hi=50.0, unit="mm", doc="lattice margin beyond the array that loads it")

    def __post_init__(self) -> None:
        if self.plate_mm > self.pitch_mm:
            raise ConfigError(f"geometry.plate_mm: {self.plate_mm} mm is wider than the pitch ({self.pitch_mm} mm)")

    @property
    def h_mm(self) -> float:
        """Fine-lattice pitch."""
        return self.pitch_mm / self.samples_per_pitch

    @property
    def pad_cells(self) -> int:
        return math.ceil(self.pad_mm / self.h_mm - 1e-9)

    @property
    def image_shape(self) -> tuple[int, int]:
        return (self.n_rows * self.samples_per_pitch, self.n_cols * self.samples_per_pitch)

    @property
    def lattice_shape(self) -> tuple[int, int]:
        """The padded lattice the stimuli press on."""
        ny, nx = self.image_shape
        return (ny + 2 * self.pad_cells, nx + 2 * self.pad_cells)


@dataclass(frozen=True)
class Cover:
    """The elastic cover (shield and top electrode layer) the objects press on; it spreads their
    pressure onto the tabs below (Boussinesq half-space, ``synth.mechanics``)."""

    thickness_mm: float = param(0.5, lo=0.01, hi=20.0, unit="mm", doc="depth of the tabs' tops")
    youngs_modulus_mpa: float = param(1.0, lo=0.01, hi=1000.0, unit="MPa", doc="for the indenters' contact law")
    poisson_ratio: float = param(0.49, lo=0.0, hi=0.5)

    @property
    def e_star_mpa(self) -> float:
        return self.youngs_modulus_mpa / (1.0 - self.poisson_ratio**2)


@dataclass(frozen=True)
class Dielectric:
    """Moulded silicone tabs of ``tab_diameter_mm`` and ``tab_height_mm`` on a ``backing_mm`` sheet,
    one tab per cell, air around them (the seed: 0.25 mm backing, 0.25-0.75 mm tabs of 1.4 mm)."""

    backing_mm: float = param(0.25, lo=0.01, hi=10.0, unit="mm")
    tab_height_mm: float = param(0.25, lo=0.01, hi=10.0, unit="mm")
    tab_diameter_mm: float = param(1.4, lo=0.05, hi=20.0, unit="mm")
    permittivity: float = param(4.0, lo=1.0, hi=100.0, doc="relative permittivity of the silicone")
    tab_modulus_mpa: float = param(
        1.95, lo=0.01, hi=1000.0, unit="MPa", doc="tab modulus: its load scale is modulus x tab area"
    )

    @property
    def tab_area_mm2(self) -> float:
        return math.pi * self.tab_diameter_mm**2 / 4

    @property
    def load_scale_n(self) -> float:
        """``F_s = E A_tab``: the load that halves the tab (MPa x mm^2 = N)."""
        return self.tab_modulus_mpa * self.tab_area_mm2


@dataclass(frozen=True)
class Hysteresis:
    """Rate-independent loading/unloading hysteresis of the tabs (a friction play, see physics).
    The loading and unloading branches are ``width = 2 a rho`` of the applied load apart (the load
    the tab feels is ``F (1 -/+ a rho)``); the widest gap of a cycle, in readings, is smaller where
    the tab curve flattens near full scale (0.065 gives the seed's ~5 % of the full response)."""

    width: float = param(0.05, lo=0.0, hi=0.5, doc="gap between the branches, share of the load (2 a rho)")
    play_share: float = param(0.5, lo=0.0, lo_open=True, hi=0.95, doc="a: share of the load carried by the play")

    @property
    def play(self) -> float:
        """``rho``: the play's half-width as a share of the load."""
        return self.width / (2 * self.play_share)

    def __post_init__(self) -> None:
        if self.play >= 1.0:
            raise ConfigError(
                f"hysteresis.width: {self.width} needs a play of {self.play:.3g} of the load (>= 1) with "
                f"play_share {self.play_share}"
            )


@dataclass(frozen=True)
class Readout:
    """Rows driven in turn with ``drive_v`` at the carrier; each column's charge amplifier with
    ``feedback_pf`` gives ``V = V_in C / C_fb`` after synchronous demodulation; ``crosstalk`` of
    each of the four neighbours' signal leaks into a cell; a common offset drifts per press; noise
    sets ``effective_bits`` over ``full_scale_g`` per cell (the seed: 7 bits over 0-200 g); then an
    ``adc_bits`` converter over ``0..adc_range_v``."""

    drive_v: float = param(5.0, lo=0.01, hi=100.0, unit="V", doc="carrier amplitude V_in")
    feedback_pf: float = param(0.5, lo=0.001, hi=1000.0, unit="pF", doc="feedback capacitor C_fb")
    crosstalk: float = param(0.015, lo=0.0, hi=0.2, doc="share of each 4-neighbour's signal read by a cell")
    full_scale_g: float = param(200.0, lo=1.0, hi=1e5, unit="g", doc="per-cell load range of the stated resolution")
    effective_bits: float = param(7.0, lo=2.0, hi=20.0, doc="effective resolution over the range (noise)")
    adc_bits: int = param(12, lo=4, hi=24)
    adc_range_v: float = param(3.3, lo=0.01, hi=100.0, unit="V")
    drift_v: float = param(0.004, lo=0.0, hi=1.0, unit="V", doc="s.d. of a press's common offset")
    drift_v_per_frame: float = param(0.0005, lo=0.0, hi=1.0, unit="V", doc="s.d. of its rate per frame")

    @property
    def lsb_v(self) -> float:
        return self.adc_range_v / 2**self.adc_bits

    @property
    def full_scale_v(self) -> float:
        """The highest code's voltage: a reading this high is saturated."""
        return (2**self.adc_bits - 1) * self.lsb_v

    @property
    def full_scale_n(self) -> float:
        return self.full_scale_g * G_TO_N


@dataclass(frozen=True)
class Device:
    """One physical array: every cell's own gain (plate area, permittivity) and tab stiffness,
    drawn once from ``seed`` (the seed: "every cell has its own, repeatable gain")."""

    seed: int = param(1, lo=0, hi=2**63 - 1, doc="draws the device's per-cell parameters")
    gain_spread: float = param(0.1, lo=0.0, hi=0.3, doc="relative s.d. of the cells' capacitance gain")
    stiffness_spread: float = param(0.1, lo=0.0, hi=0.3, doc="relative s.d. of the tabs' load scale")


@dataclass(frozen=True)
class CalibrationTable:
    """A device's fitted response (written by ``tactile-learn calibrate --task capacitive``): per
    cell (row-major) its gain and tab stiffness, and the array's crosstalk and hysteresis. The
    estimators' front end turns readings into cell loads with it; the simulation ignores it."""

    gain: tuple[float, ...] = param((), lo=0.05, hi=20.0)
    stiffness: tuple[float, ...] = param((), lo=0.05, hi=20.0)
    crosstalk: float = param(0.0, lo=0.0, hi=0.5)
    hysteresis_width: float = param(0.0, lo=0.0, hi=0.5)
    play_share: float = param(0.5, lo=0.0, lo_open=True, hi=0.95)
    presses: int = param(0, lo=0, hi=10**9, doc="presses the fit used")
    rms_residual_v: float = param(0.0, lo=0.0, hi=100.0, unit="V")

    @property
    def play(self) -> float:
        return self.hysteresis_width / (2 * self.play_share)


@dataclass(frozen=True)
class PressStimuli:
    """Presses of ``frames`` frames: every contact of a press follows the load fraction
    ``sin(pi k / (frames + 1))``, ``k = 1..frames`` (loading, then unloading; one frame: the peak).

    Contact centres are uniform over the array shrunk by ``margin_mm``; with ``pair_distance_mm``
    set, a second contact sits that far (centre to centre) from the first; with ``sweep_cells``
    (calibration rigs) press ``i`` of each batch is centred on cell ``i mod (N M)``. ``kinds`` come
    from the shape library (``synth.stimuli``). ``mask_fraction`` defines the true contact mask: the
    fine cells where a contact presses at least that share of its own mean pressure."""

    frames: int = param(8, lo=1, hi=512, doc="frames per press")
    count: tuple[int, int] = param((1, 1), lo=0, hi=8, ordered=True, doc="contacts per press, [min, max]")
    empty_fraction: float = param(0.0, lo=0.0, hi=1.0, doc="share of presses without contact")
    margin_mm: float = param(2.0, lo=-10.0, hi=50.0, unit="mm")
    pair_distance_mm: tuple[float, float] = param(
        (0.0, 0.0), lo=0.0, hi=100.0, unit="mm", ordered=True, doc="second contact's distance; [0, 0]: anywhere"
    )
    sweep_cells: bool = param(False, doc="centre press i on cell i mod N*M (a calibration rig)")
    mask_fraction: float = param(0.25, lo=0.0, lo_open=True, hi=1.0)
    kinds: tuple[StimulusKind, ...] = (StimulusKind(),)

    def __post_init__(self) -> None:
        if not self.kinds:
            raise ConfigError("stimuli.kinds: at least one stimulus kind is needed")
        unknown = sorted({k.kind for k in self.kinds} - set(KINDS))
        if unknown:  # the strips' StimulusKind validates too; kept for kinds added there later
            raise ConfigError(f"stimuli.kinds: {unknown[0]!r} is not one of {', '.join(KINDS)}")


@dataclass(frozen=True)
class CapacitiveConfig:
    geometry: ArrayGeometry = param(ArrayGeometry())
    cover: Cover = param(Cover())
    dielectric: Dielectric = param(Dielectric())
    hysteresis: Hysteresis = param(Hysteresis())
    readout: Readout = param(Readout())
    device: Device = param(Device())
    stimuli: PressStimuli = param(PressStimuli())
    calibration: CalibrationTable | None = param(None, doc="the device's fitted response (calibrate writes it)")

    def __post_init__(self) -> None:
        g, d = self.geometry, self.dielectric
        if d.tab_area_mm2 >= g.pitch_mm**2:
            raise ConfigError(
                f"dielectric.tab_diameter_mm: a {d.tab_diameter_mm} mm tab fills its {g.pitch_mm} mm cell (no air to "
                "compress into)"
            )
        if self.stimuli.margin_mm * 2 >= min(g.n_rows, g.n_cols) * g.pitch_mm:
            raise ConfigError(f"stimuli.margin_mm: {self.stimuli.margin_mm} mm leaves no room for contacts")
        cells = g.n_rows * g.n_cols
        cal = self.calibration
        if cal is not None and (len(cal.gain) != cells or len(cal.stiffness) != cells):
            raise ConfigError(
                f"calibration: gain and stiffness need {cells} values (one per cell, row-major), got "
                f"{len(cal.gain)} and {len(cal.stiffness)}"
            )

    @property
    def n_cells(self) -> int:
        return self.geometry.n_rows * self.geometry.n_cols

    @property
    def fill_fraction(self) -> float:
        """Share of a cell's tab layer that the unloaded tab fills (the rest is air)."""
        return self.dielectric.tab_area_mm2 / self.geometry.pitch_mm**2
