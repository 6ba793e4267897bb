"""Configuration of the soft strip array (the ``[strips]`` table of a scene)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import numpy as np

from synth.config import param
from synth.errors import ConfigError
from synth.sensors.strips.layouts import StripGeometry, StripLayout

__all__ = [
    "DRAWN_PARAMS",
    "ContactObject",
    "CoverLayer",
    "Holdout",
    "Piezoresistive",
    "StimulusKind",
    "StripGeometry",
    "StripReadout",
    "StripStimuli",
    "StripsConfig",
    "allowed_intervals",
    "draw_except",
]


@dataclass(frozen=True)
class CoverLayer:
    """The elastic cover the stimuli press on; row strips lie ``cover_mm`` deep, column strips a
    further ``strip_thickness_mm`` below them."""

    cover_mm: float = param(1.0, lo=0.01, hi=20.0, unit="mm", doc="cover thickness above the row strips")
    strip_thickness_mm: float = param(0.5, lo=0.0, hi=10.0, unit="mm", doc="row strip thickness")
    youngs_modulus_mpa: float = param(1.0, lo=0.01, hi=1000.0, unit="MPa", doc="cover's Young's modulus")
    poisson_ratio: float = param(0.49, lo=0.0, hi=0.5, doc="cover's Poisson ratio")
    kernel_rank_tol: float = param(1e-4, lo=1e-8, hi=0.1, doc="relative error of the separable stress kernel")

    @property
    def e_star_mpa(self) -> float:
        """Contact modulus of a rigid indenter on the cover, E / (1 - v^2)."""
        return self.youngs_modulus_mpa / (1.0 - self.poisson_ratio**2)


@dataclass(frozen=True)
class Piezoresistive:
    """Segment resistance ``R(p) = R_seg (1 + p / (g p0))^(-n)``; ``g`` is a strip's sensitivity
    gain, drawn per frame around 1 with relative spread ``gain_spread``."""

    strip_resistance_ohm: float = param(10_000.0, lo=1.0, hi=1e9, unit="ohm", doc="unloaded strip")
    p0_kpa: float = param(100.0, lo=0.1, hi=1e5, unit="kPa", doc="pressure scale of the law")
    exponent: float = param(1.0, lo=0.1, hi=5.0, doc="power-law exponent n")
    gain_spread: float = param(0.05, lo=0.0, hi=0.3, doc="relative s.d. of the per-strip sensitivity")


@dataclass(frozen=True)
class StripReadout:
    """Each strip in a divider with ``reference_ohm`` across ``supply_v``; an instrumentation
    amplifier of ``amplifier_gain`` reads the divider relative to its unloaded level (auto-zeroed
    at power-up) on top of ``offset_v``; then Gaussian noise and an ``adc_bits`` ADC over
    ``0..supply_v``."""

    supply_v: float = param(3.3, lo=0.1, hi=50.0, unit="V")
    reference_ohm: float = param(10_000.0, lo=1.0, hi=1e9, unit="ohm")
    amplifier_gain: float = param(6.0, lo=0.1, hi=1000.0)
    offset_v: float = param(0.3, lo=0.0, hi=50.0, unit="V", doc="reading of an unloaded strip")
    adc_bits: int = param(12, lo=4, hi=24)
    noise_v: float = param(0.002, lo=0.0, hi=1.0, unit="V", doc="rms electrical noise")

    def __post_init__(self) -> None:
        if self.offset_v >= self.supply_v:
            raise ConfigError(f"readout.offset_v: {self.offset_v} V must be below supply_v ({self.supply_v} V)")

    @property
    def lsb_v(self) -> float:
        return self.supply_v / 2**self.adc_bits

    @property
    def full_scale_v(self) -> float:
        """Largest reading the ADC can give: a reading this high is saturated."""
        return (2**self.adc_bits - 1) * self.lsb_v


#: the drawn parameters of a stimulus kind, in the order of their uniform draws
DRAWN_PARAMS = ("force_n", "radius_mm", "width_mm", "length_mm", "angle_deg", "hole_fraction", "tilt")


@dataclass(frozen=True)
class Holdout:
    """An interval ``[lo, hi]`` of one parameter that is never drawn (kept for held-out tests:
    e.g. blocks at 25-35 degrees are left out of training, and an evaluation family presses them at
    30 degrees)."""

    parameter: Literal["force_n", "radius_mm", "width_mm", "length_mm", "angle_deg", "hole_fraction", "tilt"]
    lo: float = param(0.0, lo=-1000.0, hi=1000.0)
    hi: float = param(0.0, lo=-1000.0, hi=1000.0)

    def __post_init__(self) -> None:
        if self.hi <= self.lo:
            raise ConfigError(f"holdout: [{self.lo}, {self.hi}] of {self.parameter} is empty (lo must be below hi)")


@dataclass(frozen=True)
class StimulusKind:
    """One kind of contact shape (``synth.stimuli``) and the ranges its parameters are drawn from
    (uniformly, minus the ``holdout`` intervals).

    ``radius_mm`` is the sphere's radius, the punch's radius, the edge's tip radius, the ring's and
    the ring terminal's outer radius, or the reach of a blob's bumps; ``width_mm`` applies to blocks,
    to a terminal's tongue and is a blob's correlation length; ``length_mm`` to blocks, edges and a
    terminal's tongue; ``angle_deg`` to blocks, edges and terminals; ``hole_fraction`` to rings and
    terminals; ``tilt`` to blocks and punches.
    """

    kind: Literal["sphere", "punch", "block", "edge", "ring", "terminal", "blob"] = "sphere"
    weight: float = param(1.0, lo=0.0, lo_open=True, hi=1e6, doc="relative frequency among kinds")
    force_n: tuple[float, float] = param((0.5, 5.0), lo=0.0, hi=1000.0, unit="N", ordered=True)
    radius_mm: tuple[float, float] = param((3.0, 8.0), lo=0.01, hi=1000.0, unit="mm", ordered=True)
    width_mm: tuple[float, float] = param((1.0, 5.0), lo=0.01, hi=1000.0, unit="mm", ordered=True)
    length_mm: tuple[float, float] = param((2.0, 10.0), lo=0.01, hi=1000.0, unit="mm", ordered=True)
    angle_deg: tuple[float, float] = param((0.0, 180.0), lo=-360.0, hi=360.0, unit="deg", ordered=True)
    hole_fraction: tuple[float, float] = param(
        (0.5, 0.5),
        lo=0.0,
        hi=0.95,
        ordered=True,
        omit_default=True,
        doc="hole radius over outer radius (rings, terminals)",
    )
    tilt: tuple[float, float] = param(
        (0.0, 0.0),
        lo=-1.0,
        hi=1.0,
        ordered=True,
        omit_default=True,
        doc="pressure slope along a block (1: zero at one end)",
    )
    holdout: tuple[Holdout, ...] = param((), omit_default=True, doc="intervals of parameters never drawn")

    def __post_init__(self) -> None:
        for name in DRAWN_PARAMS:
            lo, hi = getattr(self, name)
            if not allowed_intervals(lo, hi, self.holdouts(name)):
                raise ConfigError(f"holdout: the held-out intervals of {name} cover its whole range [{lo}, {hi}]")

    def holdouts(self, name: str) -> list[tuple[float, float]]:
        return [(h.lo, h.hi) for h in self.holdout if h.parameter == name]


def allowed_intervals(lo: float, hi: float, holes: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """``[lo, hi]`` minus the ``holes``, as sorted disjoint intervals (a point range stays a point)."""
    if lo == hi:
        return [] if any(a < lo < b for a, b in holes) else [(lo, hi)]
    pieces = [(lo, hi)]
    for a, b in holes:
        pieces = [p for s, e in pieces for p in ((s, min(e, a)), (max(s, b), e)) if p[1] > p[0]]
    return pieces


def draw_except(u: np.ndarray, lo: float, hi: float, holes: list[tuple[float, float]]) -> np.ndarray:
    """Map uniform ``u`` in [0, 1) to a uniform draw from ``[lo, hi]`` minus ``holes`` (inverse CDF
    over the allowed intervals: one number per draw, so the random stream never depends on the
    holes; without holes this is ``lo + u (hi - lo)``)."""
    if not holes:
        return lo + u * (hi - lo)
    pieces = allowed_intervals(lo, hi, holes)
    starts = np.array([s for s, _ in pieces])
    lengths = np.array([e - s for s, e in pieces])
    if lengths.sum() == 0:  # a point range
        return np.full_like(u, starts[0])
    ends = np.cumsum(lengths)
    t = u * ends[-1]
    k = np.minimum(np.searchsorted(ends, t, side="right"), len(pieces) - 1)
    return starts[k] + (t - (ends[k] - lengths[k]))


@dataclass(frozen=True)
class ContactObject:
    """One rigid object whose parts are a frame's contacts (a brick's studs, a fork's tines, a hand's
    fingertips in a row): part ``j`` (the frame's ``j``-th contact) lies ``offsets_mm[j]`` (x, y) from the
    object's centre, the offsets scaled by ``scale`` and turned by ``rotation_deg`` (both drawn per frame,
    uniformly; the rotation minus the ``rotation_holdout`` intervals, so that a block part's final angle
    can keep an evaluation's block angles held out); the rotation turns every part's own ``angle_deg``
    with it. The centre is drawn so that every part's centre lies inside the array shrunk by
    ``margin_mm``. With ``part_kinds``, part ``j`` is drawn from ``kinds[j]`` (one entry per part: a pad
    and fingertips) instead of by the kinds' weights."""

    offsets_mm: tuple[tuple[float, float], ...] = param(((0.0, 0.0),), lo=-100.0, hi=100.0, unit="mm")
    rotation_deg: tuple[float, float] = param((0.0, 0.0), lo=-360.0, hi=360.0, unit="deg", ordered=True)
    scale: tuple[float, float] = param((1.0, 1.0), lo=0.0, lo_open=True, hi=100.0, ordered=True)
    part_kinds: bool = param(False, doc="part j takes kinds[j] instead of a weighted draw")
    rotation_holdout: tuple[tuple[float, float], ...] = param(
        (),
        lo=-360.0,
        hi=360.0,
        unit="deg",
        omit_default=True,
        doc="intervals [lo, hi] of the rotation never drawn (a block part's angle turns with the object)",
    )

    def __post_init__(self) -> None:
        if not self.offsets_mm:
            raise ConfigError("stimuli.object.offsets_mm: at least one part is needed")
        for lo, hi in self.rotation_holdout:
            if hi <= lo:
                raise ConfigError(f"stimuli.object.rotation_holdout: [{lo}, {hi}] is empty (lo must be below hi)")
        if not allowed_intervals(*self.rotation_deg, list(self.rotation_holdout)):
            raise ConfigError(
                f"stimuli.object.rotation_holdout: the held-out intervals cover the whole rotation range "
                f"{list(self.rotation_deg)}"
            )

    @property
    def reach_mm(self) -> float:
        """The farthest any part's centre lies from the object's centre, at the largest scale."""
        return max(float(np.hypot(x, y)) for x, y in self.offsets_mm) * self.scale[1]


@dataclass(frozen=True)
class StripStimuli:
    """How many contacts a frame has and where: centres uniform over the array shrunk by
    ``margin_mm`` on every side (negative: centres may fall outside the array)."""

    count: tuple[int, int] = param((1, 2), lo=0, hi=16, ordered=True, doc="contacts per frame, [min, max]")
    count_weights: tuple[float, ...] = param(
        (),
        lo=0.0,
        hi=1e6,
        omit_default=True,
        doc="relative frequency of each count from min to max (default: all equally often)",
    )
    empty_fraction: float = param(0.0, lo=0.0, hi=1.0, doc="share of frames with no contact at all")
    margin_mm: float = param(0.0, lo=-20.0, hi=100.0, unit="mm")
    twin_fraction: float = param(
        0.0,
        lo=0.0,
        hi=1.0,
        doc="share of multi-contact frames whose contacts are identical (ghost-ambiguous)",
    )
    kinds: tuple[StimulusKind, ...] = (StimulusKind(),)
    object: ContactObject | None = param(
        None, omit_default=True, doc="the contacts are parts of one object (default: independent centres)"
    )

    def __post_init__(self) -> None:
        if not self.kinds:
            raise ConfigError("stimuli.kinds: at least one stimulus kind is needed")
        if self.object is not None:
            parts = len(self.object.offsets_mm)
            if self.count[1] > parts:
                raise ConfigError(f"stimuli.count: up to {self.count[1]} contacts, but the object has {parts} parts")
            if self.object.part_kinds and len(self.kinds) != parts:
                raise ConfigError(
                    f"stimuli.object.part_kinds: one kind per part is needed ({parts} parts, {len(self.kinds)} kinds)"
                )
        n_counts = self.count[1] - self.count[0] + 1
        if self.count_weights and (len(self.count_weights) != n_counts or sum(self.count_weights) <= 0):
            raise ConfigError(
                f"stimuli.count_weights: expected {n_counts} non-negative weights (one per count from "
                f"{self.count[0]} to {self.count[1]}) with a positive sum, got {list(self.count_weights)}"
            )


@dataclass(frozen=True)
class StripsConfig:
    geometry: StripGeometry = param(StripGeometry())
    layers: CoverLayer = param(CoverLayer())
    piezo: Piezoresistive = param(Piezoresistive())
    readout: StripReadout = param(StripReadout())
    stimuli: StripStimuli = param(StripStimuli())

    def wire_count(self) -> int:
        """Signal wires to the readout: one per reading (a strip end, a tap's section)."""
        return _wire_count(self.geometry)

    def __post_init__(self) -> None:
        g = self.geometry
        if self.stimuli.margin_mm * 2 >= min(g.n_rows, g.n_cols) * g.pitch_mm:
            raise ConfigError(
                f"stimuli.margin_mm: {self.stimuli.margin_mm} mm leaves no room for contacts on a "
                f"{g.n_rows * g.pitch_mm} x {g.n_cols * g.pitch_mm} mm array"
            )
        obj = self.stimuli.object
        # at any rotation the parts must fit inside the margin, or no centre could be drawn for them
        if obj is not None and 2 * obj.reach_mm > min(g.n_rows, g.n_cols) * g.pitch_mm - 2 * self.stimuli.margin_mm:
            raise ConfigError(
                f"stimuli.object: its parts reach {obj.reach_mm:g} mm from its centre; they do not fit on a "
                f"{g.n_rows * g.pitch_mm} x {g.n_cols * g.pitch_mm} mm array with a margin of "
                f"{self.stimuli.margin_mm} mm"
            )


@lru_cache(maxsize=256)
def _wire_count(geometry: StripGeometry) -> int:
    """Cached per geometry (frozen, hashable): every ``predict`` checks its input's width against it,
    and building the layout's cell weights costs ~50 us, more than the classical estimate itself."""
    return StripLayout(geometry).n_channels
