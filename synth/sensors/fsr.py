"""Force-sensing resistors (FSR400) embedded in a PDMS film (seed 002, issue 5).

Geometry (all lengths in mm, origin at the film's centre, x to the right, y up)
-----------------------------------------------------------------------------
The film is ``size_mm`` x ``size_mm`` (80 x 80) and ``thickness_mm`` (8) thick, lying on a rigid
base. Six FSR discs (``sensor_diameter_mm`` = 5) lie on one plane ``sensor_depth_mm`` (6) below
the surface, at the three corners and the three edge midpoints of an equilateral triangle of side
``2 * side_mm`` (40) whose centroid is the film's centre. They form four equilateral triangles of
side ``side_mm`` (20), as in the paper::

                         S0 (0, +23.09)
                        /  \\            T0 = (S0, S3, S4)   top
                      / T0  \\           T1 = (S1, S5, S3)   bottom left
        (-10, 5.77) S3------S4 (10, 5.77)
                  / \\  T3  / \\          T2 = (S2, S4, S5)   bottom right
                /T1  \\    /  T2\\        T3 = (S3, S4, S5)   centre (upside down)
     (-20,-11.55) S1----S5----S2 (20, -11.55)
                     (0, -11.55)

Stimuli: a round (spherical) indenter tip, radius drawn from ``tip_radii_mm``, pressed with a
force from ``force_range_n`` (log-uniform) at one point per frame; a fraction of the frames has no
contact. Contact centres are uniform inside the four triangles for a fraction ``inside_fraction``
of the contacts and uniform over the whole film (less ``edge_margin_mm``) otherwise.

Forward model, one stage per function (tests check each)
--------------------------------------------------------
1. Surface pressure: Hertz, ``a = (3 F R / (4 E*))^(1/3)``, ``p(r) = 3F/(2 pi a^2) sqrt(1 - r^2/a^2)``.
2. Load reaching each sensor disc (:class:`Transfer`): the surface pressure convolved with a
   vertical-stress kernel and averaged over the sensor's disc, times the disc's area. The kernel is

       k(r) = layer_gain * B(r; z) + share_gain * B(r; share_length_mm),
       B(r; h) = 3 h^3 / (2 pi (r^2 + h^2)^(5/2))      (Boussinesq, unit point load at depth h)

   * ``B(r; z)`` at the sensors' depth ``z`` = 6 mm is the first-order half-space model.
   * ``layer_gain`` is the finite-layer correction: an 8 mm layer bonded to a rigid base
     concentrates the stress under the load compared with the half-space (factor > 1).
   * ``share_gain * B(r; share_length_mm)`` is load sharing: an FSR400 is a PET laminate some
     three orders of magnitude stiffer than PDMS, sitting 2 mm above the rigid base, so each disc is
     a hard spot that draws load from a catchment much wider than the free-field stress under it
     (as piles do under a piled raft). It is modelled as a second, wider Boussinesq-shaped term.
   All terms are radial, so the disc-averaged transfer depends only on the distance from the
   contact to the sensor and on the Hertz radius; it is computed once per configuration by a Hankel
   transform (``(1 + k h) exp(-k h)`` for ``B``, ``2 J1(kb)/(kb)`` for the disc,
   ``3 (sin x - x cos x) / x^3`` for the Hertz profile) and tabulated.
3. FSR conductance (:class:`FsrLaw`), per sensor: ``G = G_leak + gain * c * F_sat *
   tanh(F * s((F - F_break) / w) / F_sat)``: zero below the break force (logistic turn-on of width
   ``w``), proportional to force above it (resistance ~ 1/F, the datasheet's law), softly saturating
   near ``F_sat``. ``gain`` is the part's gain: each film draws its six gains with a part-to-part
   spread (datasheet +/-6 %), and each press multiplies them by a repeatability factor (+/-2 %).
   Both are uniform over the datasheet's whole band by default (every part the datasheet allows
   is drawn, up to its limits); ``distribution = "normal"`` reads the figures as one sigma instead
   (harder: a third of the parts outside the band), truncated at 3 sigma.
4. Readout (:class:`Readout`): voltage divider ``V = Vcc G R_m / (1 + G R_m)``, then an ADC of
   ``adc_bits`` (<= 10) bits with Gaussian input noise ``noise_lsb`` (rms, in LSB) before
   quantisation. Readings are ADC codes as float32.

Noise (film gain spread, press repeatability, ADC noise) and readout (divider + quantisation) are
separate parts: ``scene.noise = false`` switches every noise source off (all films nominal) and
keeps the deterministic readout.

Films. A film is six gain draws. ``simulate`` draws one film per ``frames_per_film`` frames from the
generator it is given; each film has a 62-bit id and its gains are a pure function of that id
(:func:`film_gains`), so a dataset generated with another seed (or another shard) holds other
films. Accuracy must always be measured on films training never saw: generate the test set with a
different seed. A scene whose ``[fsr.film] gains`` is set describes one calibrated film instead:
every frame uses those gains (``tactile-learn calibrate --task fsr`` writes such a scene).

Mind the magnitudes: choosing the unknowns
------------------------------------------
With the pure half-space kernel (``layer_gain = 1``, ``share_gain = 0``) a 10 N load at the
centroid of a triangle (11.5 mm from its three sensors) puts ~0.06 N on each sensor, below the
FSR400's break force, yet the paper located contacts to 2.5 mm. The film's real load path is not in
the paper's copy, so its three unknowns were set so that the paper's own kind of algorithm lands
near the paper's figures: the closed-form three-sensor triangulation with the half-space kernel at
the sensors' depth, its amplitude and force scale fitted to the film's noise-free response
(``tactile_learn.estimators.classical.triangulation``, as the paper calibrated with FEA), on the
paper's conditions (contacts inside the triangles, 1-10 N), uncalibrated films never seen before.

Chosen: ``layer_gain = 1.5``, ``share_gain = 10``, ``share_length_mm = 16``,
``break_force_n = 0.15`` (the FSR400's actuation force is 0.1-0.2 N). Evidence
(``python scripts/fsr_calibrate_model.py``; 3000 frames per setting, seed 20240):

==================================  ========  ========  ========  =========
disc load per newton at distance    0 mm      11.5 mm   20 mm     30 mm
==================================  ========  ========  ========  =========
pure half-space                     0.211     0.0059    0.0005    0.0001
this film                           0.671     0.138     0.036     0.009
==================================  ========  ========  ========  =========

- the six discs together never carry more than 0.82 of the applied load (base carries the rest);
- triangulation on held-out films: median localisation error 2.75 mm (paper 2.5 mm), force
  accuracy 88.2 % (paper 88.23 %); on the 20 000-frame test set of ``scripts/fsr_results.py``
  (seed 3, 313 unseen films): 2.78 mm and 88.0 %;
- the sweep around the choice (``layer_gain`` 1.5, ``share_length_mm`` 16): less load sharing
  (``share_gain`` 6) leaves a triangle's far sensors below the break force too often (force
  accuracy 0.67-0.87 for break forces 0.2-0.1 N); more (14) makes the film easier than the paper
  (0.89-0.94) and lets the discs carry more than the applied load (up to 1.02 of it); at
  ``share_gain`` 10 the break force moves the force accuracy from 0.93 (0.1 N) to 0.82 (0.2 N).
  The median localisation error is the half-space kernel's misfit to this film's wider load path
  (2-3.5 mm over the whole sweep).

The same closed form with a fitted effective kernel (``triangulation_fit``) gets 0.42 mm and 89.8 %
on the same test set: the film is not easier than the paper for a better classical model either.

Model limits: linear elasticity with radial kernels (no free film edges, no friction, no
viscoelastic creep or FSR drift/hysteresis); the load-sharing term is an effective model whose two
parameters were calibrated, not derived.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from scipy import special

from synth.config import param
from synth.errors import ConfigError
from synth.sensors.base import ArraySpec

__all__ = [
    "CONFIG_CLASS",
    "DEFAULT_OUTPUTS",
    "N_SENSORS",
    "OUTPUTS",
    "TRIANGLES",
    "FilmConfig",
    "FsrConfig",
    "FsrElementConfig",
    "FsrLaw",
    "FsrSimulator",
    "LayoutConfig",
    "Readout",
    "ReadoutConfig",
    "StimulusConfig",
    "Transfer",
    "TransferConfig",
    "film_gains",
    "flat_sensor_loads",
    "hertz_radius_mm",
    "in_triangles",
    "make_simulator",
    "sensor_positions",
    "triangle_vertices",
]

N_SENSORS = 6
#: sensor indices of the four triangles (top, bottom left, bottom right, centre)
TRIANGLES: tuple[tuple[int, int, int], ...] = ((0, 3, 4), (1, 5, 3), (2, 4, 5), (3, 4, 5))

# ---- configuration ---------------------------------------------------------------------------


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


CONFIG_CLASS = FsrConfig

OUTPUTS: dict[str, str] = {
    "readings": "readings (6,): ADC codes of the six FSR dividers (float32)",
    "truth": "xy_mm (2,) contact centre and force_n () applied force (0 = no contact)",
    "sensor_force": "sensor_force_n (6,): noise-free load on each sensor disc (N)",
    "latent": "latent_*: film id and gains, press gains, xy, force, tip radius, contact flag",
}
DEFAULT_OUTPUTS: tuple[str, ...] = ("readings", "truth", "latent")


# ---- geometry --------------------------------------------------------------------------------


def sensor_positions(layout: LayoutConfig) -> np.ndarray:
    """(6, 2) sensor centres in mm (order S0..S5 of the module docstring), float64."""
    s = layout.side_mm
    h = 2.0 * s * math.sqrt(3.0) / 2.0  # height of the big triangle (side 2s)
    top = (0.0, 2.0 * h / 3.0)
    left = (-s, -h / 3.0)
    right = (s, -h / 3.0)
    corners = np.array([top, left, right])
    mids = np.array([(corners[0] + corners[1]) / 2, (corners[0] + corners[2]) / 2, (corners[1] + corners[2]) / 2])
    return np.concatenate([corners, mids]).astype(np.float64)


def triangle_vertices(layout: LayoutConfig) -> np.ndarray:
    """(4, 3, 2) vertices of the four triangles, in the order of :data:`TRIANGLES`."""
    pos = sensor_positions(layout)
    return pos[np.array(TRIANGLES)]


def barycentric(xy: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (..., T, 3) of points ``xy`` (..., 2) in triangles ``tri`` (T, 3, 2)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]  # (T, 2)
    v0, v1 = b - a, c - a
    det = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]  # (T,) twice the signed area: nonzero for a valid layout
    d = xy[..., None, :] - a  # (..., T, 2)
    l1 = (d[..., 0] * v1[:, 1] - d[..., 1] * v1[:, 0]) / det
    l2 = (v0[:, 0] * d[..., 1] - v0[:, 1] * d[..., 0]) / det
    return np.stack([1.0 - l1 - l2, l1, l2], axis=-1)


def in_triangles(xy: np.ndarray, layout: LayoutConfig, tol_mm: float = 0.0) -> np.ndarray:
    """Bool (...,): is each point inside (or within ``tol_mm`` of) one of the four triangles?"""
    lam = barycentric(np.asarray(xy, dtype=np.float64), triangle_vertices(layout))
    # a barycentric coordinate of -t is a distance t * height outside the opposite edge
    height = layout.side_mm * math.sqrt(3.0) / 2.0
    return np.asarray((lam.min(axis=-1) >= -tol_mm / height).any(axis=-1))


# ---- stage 1-2: contact mechanics and load transfer ------------------------------------------


def hertz_radius_mm(force_n: np.ndarray, tip_radius_mm: np.ndarray, layout: LayoutConfig) -> np.ndarray:
    """Hertz contact radius ``a = (3 F R / (4 E*))^(1/3)`` (mm) of a rigid sphere on the film."""
    e_star = layout.youngs_modulus_mpa / (1.0 - layout.poisson**2)  # N/mm^2; poisson <= 0.5 keeps it finite
    f = np.maximum(np.asarray(force_n, dtype=np.float64), 0.0)
    return np.cbrt(3.0 * f * np.asarray(tip_radius_mm, dtype=np.float64) / (4.0 * e_star))


def _hertz_hat(x: np.ndarray) -> np.ndarray:
    """Hankel transform of the unit-force Hertz profile, ``3 (sin x - x cos x) / x^3``."""
    small = x < 1e-2
    xs = np.where(small, 1.0, x)  # avoid 0/0; the series is used there
    exact = 3.0 * (np.sin(xs) - xs * np.cos(xs)) / xs**3
    return np.where(small, 1.0 - x * x / 10.0, exact)


def _disc_hat(x: np.ndarray) -> np.ndarray:
    """Hankel transform of the unit-area disc indicator, ``2 J1(x) / x``."""
    small = x < 1e-4
    xs = np.where(small, 1.0, x)  # avoid 0/0; limit 1 there
    return np.where(small, 1.0 - x * x / 8.0, 2.0 * special.j1(xs) / xs)


def boussinesq(r_mm: np.ndarray, depth_mm: float) -> np.ndarray:
    """Vertical stress (N/mm^2 per N) at depth ``h`` and horizontal distance ``r`` from a unit point load."""
    h = float(depth_mm)
    r2 = np.asarray(r_mm, dtype=np.float64) ** 2
    return 3.0 * h**3 / (2.0 * np.pi * (r2 + h * h) ** 2.5)  # h > 0 keeps the base positive


@dataclass(frozen=True)
class Transfer:
    """Load (N) on each sensor disc per newton applied, as a function of distance and Hertz radius.

    ``table[i, j]`` is the disc load per newton at distance ``d_grid[i]`` for Hertz radius
    ``a_grid[j]``; :meth:`per_newton` interpolates bilinearly (beyond the grid: the far-field
    point-load formula in distance, the last column in radius).
    """

    d_grid: np.ndarray
    a_grid: np.ndarray
    table: np.ndarray
    depth_mm: float
    disc_radius_mm: float
    layer_gain: float
    share_gain: float
    share_length_mm: float

    def kernel_hat(self, k: np.ndarray) -> np.ndarray:
        """Hankel transform of the point-load kernel (without disc and Hertz)."""
        z, ell = self.depth_mm, self.share_length_mm
        return self.layer_gain * (1.0 + k * z) * np.exp(-k * z) + self.share_gain * (1.0 + k * ell) * np.exp(-k * ell)

    def point_kernel(self, r_mm: np.ndarray) -> np.ndarray:
        """Point-load stress kernel k(r) (N/mm^2 per N) at the sensors' depth."""
        return self.layer_gain * boussinesq(r_mm, self.depth_mm) + self.share_gain * boussinesq(
            r_mm, self.share_length_mm
        )

    def per_newton(self, d_mm: np.ndarray, a_mm: np.ndarray) -> np.ndarray:
        """Disc load per newton for distances ``d_mm`` and Hertz radii ``a_mm`` (broadcast), float64."""
        d = np.asarray(d_mm, dtype=np.float64)
        a = np.asarray(a_mm, dtype=np.float64)
        d, a = np.broadcast_arrays(d, a)
        dg, ag = self.d_grid, self.a_grid
        di = np.clip((d - dg[0]) / (dg[1] - dg[0]), 0.0, len(dg) - 1.000001)
        ai = np.clip((a - ag[0]) / (ag[1] - ag[0]), 0.0, len(ag) - 1.000001)
        i0, j0 = di.astype(np.int64), ai.astype(np.int64)
        fi, fj = di - i0, ai - j0
        t = self.table
        out = (
            t[i0, j0] * (1 - fi) * (1 - fj)
            + t[i0 + 1, j0] * fi * (1 - fj)
            + t[i0, j0 + 1] * (1 - fi) * fj
            + t[i0 + 1, j0 + 1] * fi * fj
        )
        far = d > dg[-1]
        if far.any():
            area = np.pi * self.disc_radius_mm**2
            out = np.where(far, area * self.point_kernel(d), out)
        return out


def _hankel_table(
    d_grid: np.ndarray,
    a_grid: np.ndarray,
    depth: float,
    b: float,
    layer_gain: float,
    share_gain: float,
    ell: float,
) -> np.ndarray:
    """Disc-averaged load per newton (table over d, a) by numerical inverse Hankel transform."""
    # Gauss-Legendre panels (no endpoint error, unlike the trapezoid rule, which leaves an O(dk^2)
    # bias that dominates the tiny far-field values); panels narrow enough for J0(k d_max)
    k_max = 60.0 / min(depth, ell)  # the kernel decays like exp(-k h): exp(-60) is far below float64 eps
    width = min(0.05, 2.0 / max(float(d_grid[-1]), 1.0))
    n_panels = math.ceil(k_max / width)
    nodes, weights = np.polynomial.legendre.leggauss(12)
    left = np.arange(n_panels) * width
    k = (left[:, None] + (nodes[None, :] + 1.0) * width / 2.0).ravel()
    w = np.tile(weights * width / 2.0, n_panels)
    kern = layer_gain * (1.0 + k * depth) * np.exp(-k * depth) + share_gain * (1.0 + k * ell) * np.exp(-k * ell)
    base = kern * _disc_hat(k * b) * k * w / (2.0 * np.pi)  # (K,)
    hertz = _hertz_hat(k[None, :] * a_grid[:, None])  # (A, K)
    bessel = special.j0(d_grid[:, None] * k[None, :])  # (D, K)
    stress = bessel @ (base[:, None] * hertz.T)  # (D, A): mean stress over the disc per newton
    return np.maximum(stress, 0.0) * (np.pi * b * b)


@functools.lru_cache(maxsize=16)
def _transfer_cached(
    depth: float, b: float, layer_gain: float, share_gain: float, ell: float, d_max: float, a_max: float
) -> Transfer:
    d_grid = np.linspace(0.0, d_max, round(d_max / 0.125) + 1)
    a_grid = np.linspace(0.0, a_max, round(a_max / 0.1) + 1)
    table = _hankel_table(d_grid, a_grid, depth, b, layer_gain, share_gain, ell)
    table.setflags(write=False)
    return Transfer(d_grid, a_grid, table, depth, b, layer_gain, share_gain, ell)


def make_transfer(config: FsrConfig) -> Transfer:
    """The (cached) transfer table for a configuration."""
    lay, tr, st = config.layout, config.transfer, config.stimulus
    a_max = float(hertz_radius_mm(np.array(st.force_range_n[1]), np.array(max(st.tip_radii_mm)), lay))
    a_max = max(0.5, math.ceil(a_max * 10.0 + 1.0) / 10.0)
    d_max = float(math.ceil(lay.size_mm * math.sqrt(2.0) + 2.0))
    return _transfer_cached(
        lay.sensor_depth_mm,
        lay.sensor_diameter_mm / 2.0,
        tr.layer_gain,
        tr.share_gain,
        tr.share_length_mm,
        d_max,
        a_max,
    )


def sensor_loads(config: FsrConfig, xy_mm: np.ndarray, force_n: np.ndarray, tip_radius_mm: np.ndarray) -> np.ndarray:
    """Noise-free load (N) on each of the six discs, (B, 6) float64, for contacts (B, 2), (B,), (B,).

    A force of 0 means no contact and gives zero load.
    """
    xy = np.asarray(xy_mm, dtype=np.float64).reshape(-1, 2)
    force = np.asarray(force_n, dtype=np.float64).reshape(-1)
    tip = np.broadcast_to(np.asarray(tip_radius_mm, dtype=np.float64), force.shape)
    pos = sensor_positions(config.layout)
    d = np.linalg.norm(xy[:, None, :] - pos[None, :, :], axis=-1)  # (B, 6)
    a = hertz_radius_mm(force, tip, config.layout)[:, None]
    return make_transfer(config).per_newton(d, a) * np.maximum(force, 0.0)[:, None]


#: points that stand for a flat indenter's disc of uniform pressure (sunflower pattern)
FLAT_POINTS = 64


def flat_sensor_loads(config: FsrConfig, xy_mm: np.ndarray, force_n: np.ndarray, radius_mm: np.ndarray) -> np.ndarray:
    """Noise-free disc loads (B, 6) of flat indenters: uniform pressure on a disc of ``radius_mm``
    around ``xy_mm``, as :data:`FLAT_POINTS` equal point loads spread evenly over the disc (the load
    path is linear, so the loads add)."""
    xy = np.asarray(xy_mm, dtype=np.float64).reshape(-1, 2)
    force = np.asarray(force_n, dtype=np.float64).reshape(-1)
    radius = np.broadcast_to(np.asarray(radius_mm, dtype=np.float64), force.shape)
    k = np.arange(FLAT_POINTS) + 0.5
    # sunflower: equal area per point; the golden angle keeps neighbours apart
    rho = np.sqrt(k / FLAT_POINTS)
    phi = k * np.pi * (3.0 - math.sqrt(5.0))
    offsets = np.stack([rho * np.cos(phi), rho * np.sin(phi)], axis=1)  # (K, 2) on the unit disc
    points = xy[:, None, :] + radius[:, None, None] * offsets[None]  # (B, K, 2)
    d = np.linalg.norm(points[:, :, None, :] - sensor_positions(config.layout)[None, None], axis=-1)  # (B, K, 6)
    per_newton = make_transfer(config).per_newton(d, np.zeros_like(d)).mean(axis=1)
    return per_newton * np.maximum(force, 0.0)[:, None]


# ---- stage 3: the FSR ------------------------------------------------------------------------


@dataclass(frozen=True)
class FsrLaw:
    """Conductance (uS) of one FSR400 against the load on its disc (N), and its inverse."""

    config: FsrElementConfig

    def shape(self, load_n: np.ndarray) -> np.ndarray:
        """Force-equivalent response ``F_sat tanh(F s((F - Fb)/w) / F_sat)`` (N), gain 1, no leak."""
        c = self.config
        f = np.maximum(np.asarray(load_n, dtype=np.float64), 0.0)
        gate = special.expit((f - c.break_force_n) / c.break_width_n)  # width > 0 (validated)
        return c.saturation_force_n * np.tanh(f * gate / c.saturation_force_n)

    def conductance_us(self, load_n: np.ndarray, gain: np.ndarray | float = 1.0) -> np.ndarray:
        """Conductance (uS) for loads (N) and part gains (broadcast)."""
        c = self.config
        return c.leak_conductance_us + np.asarray(gain) * c.conductance_us_per_n * self.shape(load_n)

    @functools.cached_property
    def _inverse_table(self) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        lo = max(c.break_force_n - 12.0 * c.break_width_n, 1e-6)
        loads = np.concatenate(
            [np.linspace(0.0, lo, 64, endpoint=False), np.geomspace(lo, 50.0 * c.saturation_force_n, 4000)]
        )
        shape = self.shape(loads)
        # shape is strictly increasing above ~0 (derivative > 0); keep it strictly increasing for interp
        keep = np.concatenate([[True], np.diff(shape) > 1e-300])
        return shape[keep], loads[keep]

    def load_from_shape(self, shape: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`shape` (N); responses at or above saturation map to the table's end."""
        s_tab, f_tab = self._inverse_table
        return np.interp(np.asarray(shape, dtype=np.float64), s_tab, f_tab)

    def load_from_conductance(self, conductance_us: np.ndarray, gain: np.ndarray | float = 1.0) -> np.ndarray:
        """Load (N) from conductance (uS) and part gain; at or below the leak gives 0."""
        c = self.config
        excess = np.maximum(np.asarray(conductance_us, dtype=np.float64) - c.leak_conductance_us, 0.0)
        # gain > 0 (validated, >= 0.05); conductance_us_per_n > 0 (validated)
        shape = excess / (np.asarray(gain) * c.conductance_us_per_n)
        return self.load_from_shape(shape)


# ---- stage 4: readout ------------------------------------------------------------------------


@dataclass(frozen=True)
class Readout:
    """Voltage divider and ADC: conductance (uS) <-> ADC code. Noise is a separate argument."""

    config: ReadoutConfig

    @property
    def full_scale(self) -> int:
        """Largest ADC code."""
        return int(2**self.config.adc_bits - 1)

    def fraction(self, conductance_us: np.ndarray) -> np.ndarray:
        """Divider output as a fraction of the supply, ``G R / (1 + G R)``, in [0, 1)."""
        gr = np.maximum(np.asarray(conductance_us, dtype=np.float64), 0.0) * self.config.divider_kohm * 1e-3
        return gr / (1.0 + gr)  # 1 + gr >= 1

    def codes(self, conductance_us: np.ndarray, noise: np.ndarray | None = None, quantise: bool = True) -> np.ndarray:
        """ADC codes (float64) for conductances; ``noise`` (same shape, in LSB) is added before quantising."""
        levels = 2**self.config.adc_bits
        analog = self.fraction(conductance_us) * levels
        if noise is not None:
            analog = analog + noise
        if quantise:
            return np.clip(np.floor(analog), 0.0, levels - 1.0)
        return np.clip(analog - 0.5, 0.0, levels - 1.0)

    def conductance_us(self, codes: np.ndarray) -> np.ndarray:
        """Inverse readout: code -> conductance (uS), taking each code at the centre of its bin."""
        levels = 2**self.config.adc_bits
        v = (np.asarray(codes, dtype=np.float64) + 0.5) / levels
        v = np.clip(v, 0.5 / levels, 1.0 - 0.5 / levels)  # keeps 1 - v >= half a bin: no division by 0
        return v / (1.0 - v) / (self.config.divider_kohm * 1e-3)


# ---- films -----------------------------------------------------------------------------------


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


# ---- simulator -------------------------------------------------------------------------------


@dataclass
class FsrSimulator:
    """Simulator for a scene with task ``fsr`` (see the module docstring)."""

    config: FsrConfig
    outputs: tuple[str, ...]
    noise: bool = True
    law: FsrLaw = field(init=False)
    readout: Readout = field(init=False)

    def __post_init__(self) -> None:
        self.law = FsrLaw(self.config.element)
        self.readout = Readout(self.config.readout)

    def output_specs(self) -> dict[str, ArraySpec]:
        specs: dict[str, ArraySpec] = {}
        if "readings" in self.outputs:
            specs["readings"] = ArraySpec((N_SENSORS,), "float32", "ADC codes of S0..S5")
        if "truth" in self.outputs:
            specs["xy_mm"] = ArraySpec((2,), "float32", "contact centre (mm, film centre origin); 0 if none")
            specs["force_n"] = ArraySpec((), "float32", "applied force (N); 0 = no contact")
        if "sensor_force" in self.outputs:
            specs["sensor_force_n"] = ArraySpec((N_SENSORS,), "float32", "noise-free disc loads (N)")
        if "latent" in self.outputs:
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

    def _loads(self, contacts: dict[str, np.ndarray], unusual: dict[str, np.ndarray] | None) -> np.ndarray:
        cfg = self.config
        loads = sensor_loads(cfg, contacts["xy"], contacts["force"], contacts["tip"])
        if unusual is None:
            return loads
        flat = unusual["flat"]
        if flat.any():
            loads[flat] = flat_sensor_loads(
                cfg, contacts["xy"][flat], contacts["force"][flat], unusual["flat_radius"][flat]
            )
        second = unusual["second"]
        if second.any():
            loads[second] += sensor_loads(
                cfg, unusual["second_xy"][second], unusual["second_force"][second], unusual["second_tip"][second]
            )
        return loads

    # -- stimulus
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

    # -- films
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

    def simulate(self, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        cfg = self.config
        contacts = self.draw_contacts(n, rng)
        film_id, gain = self.draw_films(n, rng)
        z_rep = _unit_draw(rng, (n, N_SENSORS), cfg.film.distribution)
        z_adc = rng.standard_normal((n, N_SENSORS))  # drawn always: the stream does not depend on noise
        unusual = self.draw_unusual(contacts, rng) if cfg.stimulus.unusual else None
        press_gain = gain * (1.0 + cfg.film.repeatability * z_rep) if self.noise else gain
        out: dict[str, np.ndarray] = {}
        need_load = any(o in self.outputs for o in ("readings", "sensor_force"))
        if need_load:
            loads = self._loads(contacts, unusual)
            if "sensor_force" in self.outputs:
                out["sensor_force_n"] = loads.astype(np.float32)
            if "readings" in self.outputs:
                conductance = self.law.conductance_us(loads, press_gain)
                noise = cfg.readout.noise_lsb * z_adc if self.noise else None
                out["readings"] = self.readout.codes(conductance, noise).astype(np.float32)
        if "truth" in self.outputs:
            out["xy_mm"] = contacts["xy"].astype(np.float32)
            out["force_n"] = contacts["force"].astype(np.float32)
        if "latent" in self.outputs:
            out["latent_film_id"] = film_id.astype(np.int64)
            out["latent_gain"] = gain.astype(np.float32)
            out["latent_press_gain"] = press_gain.astype(np.float32)
            out["latent_xy_mm"] = contacts["xy"].astype(np.float32)
            out["latent_force_n"] = contacts["force"].astype(np.float32)
            out["latent_tip_radius_mm"] = contacts["tip"].astype(np.float32)
            out["latent_contact"] = contacts["contact"].astype(np.bool_)
            if unusual is not None:
                out["latent_n_presses"] = (contacts["contact"].astype(np.int8) + unusual["second"]).astype(np.int8)
                out["latent_flat"] = unusual["flat"]
                out["latent_flat_radius_mm"] = unusual["flat_radius"].astype(np.float32)
                out["latent_second_xy_mm"] = unusual["second_xy"].astype(np.float32)
                out["latent_second_force_n"] = unusual["second_force"].astype(np.float32)
        return out

    # -- physics API for tests and estimators
    def forward(
        self,
        xy_mm: np.ndarray,
        force_n: np.ndarray,
        tip_radius_mm: np.ndarray | float,
        gains: np.ndarray | float = 1.0,
        rng: np.random.Generator | None = None,
        quantise: bool = True,
    ) -> np.ndarray:
        """Readings (B, 6) float64 of given contacts on a film with ``gains``; ``rng`` adds ADC noise."""
        force = np.asarray(force_n, dtype=np.float64).reshape(-1)
        loads = sensor_loads(self.config, xy_mm, force, np.broadcast_to(tip_radius_mm, force.shape))
        conductance = self.law.conductance_us(loads, gains)
        noise = None if rng is None else self.config.readout.noise_lsb * rng.standard_normal(loads.shape)
        return self.readout.codes(conductance, noise, quantise=quantise)

    def loads_from_readings(self, readings: np.ndarray, gains: np.ndarray | float = 1.0) -> np.ndarray:
        """Inverse readout and FSR law: disc loads (N) from ADC codes, for part ``gains``."""
        return self.law.load_from_conductance(self.readout.conductance_us(readings), gains)


def make_simulator(scene: Any) -> FsrSimulator:
    """Simulator for ``scene`` (task ``fsr``): computes only the outputs the scene asks for."""
    return FsrSimulator(scene.sensor, tuple(scene.outputs), bool(scene.noise))
