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

The values of the film's three unknowns and the evidence for them are in the README ("FSR film:
choosing the unknowns"; ``python scripts/fsr_calibrate_model.py``).

Model limits: linear elasticity with radial kernels (no free film edges, no friction, no
viscoelastic creep or FSR drift/hysteresis); the load-sharing term is an effective model whose two
parameters were calibrated, not derived.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy import special

from synth.sensors.fsr.config import FsrConfig, LayoutConfig
from synth.sensors.fsr.geometry import sensor_positions

__all__ = [
    "FLAT_POINTS",
    "Transfer",
    "boussinesq",
    "flat_sensor_loads",
    "hertz_radius_mm",
    "make_transfer",
    "sensor_loads",
]

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
