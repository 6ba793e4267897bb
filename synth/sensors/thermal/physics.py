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
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy import special

from synth.errors import InputError

__all__ = [
    "ABSOLUTE_ZERO_C",
    "ContactModel",
    "contact_excess",
    "phi",
    "recovery_excess",
    "spreading_conductance",
    "touch_excess",
]


# -------------------------------------------------------------------------------------------------
# physics: the analytic contact solution

#: no temperature (degC) of an object, a room or a recording can be at or below this
ABSOLUTE_ZERO_C = -273.15

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
    """Roots (..., 3) of the cubics ``coef`` (..., 4): a closed form (:func:`_direct_roots`; the
    companion-matrix eigenvalues where it fails its check), two Newton steps.

    ``numpy.linalg.eigvals`` of 3 x 3 matrices costs ~2 us a matrix (LAPACK's set-up per matrix),
    ~15 us of a simulated touch; the closed form is a few vector operations. Both start Newton
    close enough that its two steps end at the root to rounding."""
    a = coef[..., 1:] / coef[..., :1]  # a3 = C e > 0
    with np.errstate(all="ignore"):  # a failed closed form (0/0, arccos of a rounded 1 + eps) is caught below
        r = _polish(_direct_roots(a), a)
        # the three roots must be the cubic's (finite, and sum and product as Vieta's): a double
        # root or a cancelling case sends its cubic to the eigen-solver
        scale = np.abs(r).sum(axis=-1)
        ok = np.isfinite(r).all(axis=-1)
        ok &= np.abs(r.sum(axis=-1) + a[..., 0]) <= 1e-9 * scale
        ok &= np.abs(r.prod(axis=-1) + a[..., 2]) <= 1e-9 * np.abs(r).prod(axis=-1)
    if not ok.all():
        bad = ~ok
        comp = np.zeros((int(bad.sum()), 3, 3))
        comp[:, 0, :] = -a[bad]
        comp[:, 1, 0] = 1.0
        comp[:, 2, 1] = 1.0
        r[bad] = _polish(np.linalg.eigvals(comp).astype(np.complex128), a[bad])
    return r


def _polish(r: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Two Newton steps on the monic cubics ``a`` (..., 3) (a root finder's error is relative to
    the largest root; after these the small roots are exact to rounding too)."""
    for _ in range(2):
        f = ((r + a[..., :1]) * r + a[..., 1:2]) * r + a[..., 2:3]
        df = (3 * r + 2 * a[..., :1]) * r + a[..., 1:2]
        ok = np.abs(df) > 0  # a double root: keep it as it is (handled by the nudge)
        r = np.where(ok, r - f / np.where(ok, df, 1.0), r)
    return r


def _direct_roots(a: np.ndarray) -> np.ndarray:
    """Roots (..., 3) of ``q^3 + a1 q^2 + a2 q + a3`` (real ``a`` (..., 3), ``a3 != 0``) in closed
    form: one real root (Cardano's, or the trigonometric form when all three are real), the other
    two from Vieta's relations by whichever of the two forms does not cancel."""
    batch = a.shape[:-1]
    a = a.reshape(-1, 3)  # flat: the rare three-real-roots case is filled in by index
    a1, a2, a3 = a[:, 0], a[:, 1], a[:, 2]
    shift = a1 / 3.0  # q = t - shift: t^3 + P t + Q = 0
    pp = a2 - a1 * shift
    qq = a3 - shift * a2 + 2.0 * shift**3
    disc = (qq / 2.0) ** 2 + (pp / 3.0) ** 3
    # one real root (disc > 0): the larger cube root first, the other as -P / (3 A) (no cancellation)
    big = -np.copysign(np.cbrt(np.abs(qq) / 2.0 + np.sqrt(np.maximum(disc, 0.0))), qq)
    t_one = big - pp / (3.0 * np.where(big != 0, big, 1.0))
    # three real roots (disc <= 0, P < 0): t = m cos(theta), the largest (only where needed: the
    # seed's sensor has a complex pair, so this is the rare case)
    three = disc <= 0
    if three.any():
        m = 2.0 * np.sqrt(np.maximum(-pp[three], 0.0) / 3.0)
        theta = np.arccos(np.clip(3.0 * qq[three] / (pp[three] * m), -1.0, 1.0)) / 3.0
        t_one[three] = m * np.cos(theta)
    r1 = t_one - shift
    # the other two: product -a3 / r1, sum -a1 - r1 (cancels when r1 ~ -a1: then (a2 - prod) / r1)
    prod = -a3 / r1
    total = np.where(r1 * r1 < np.abs(prod), -a1 - r1, (a2 - prod) / r1)
    half = total / 2.0
    d = half * half - prod
    root_d = np.sqrt(np.abs(d))
    # a real pair: the larger one by adding like signs, the smaller as prod / larger
    far = half + np.copysign(root_d, half)
    near = prod / np.where(far != 0, far, 1.0)
    r2 = np.where(d < 0, half + 1j * root_d, far)
    r3 = np.where(d < 0, half - 1j * root_d, near)
    return np.stack([r1 + 0j, r2, r3], axis=-1).reshape(*batch, 3)


def _min_gap(r: np.ndarray) -> np.ndarray:
    """Smallest pairwise root distance relative to the larger of the two roots (0 for a double root)."""
    first, second = r[..., [0, 0, 1]], r[..., [1, 2, 2]]  # the three pairs side by side
    scale = np.maximum(np.maximum(np.abs(first), np.abs(second)), 1e-300)  # avoids 0/0
    return (np.abs(first - second) / scale).min(axis=-1)


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
        values = (c, g, h, e, ks, v0_, s)
        # one check over all parameters (a model is built per fit iteration: a check per name cost
        # more than the arithmetic at batch 1); the loops below name the problem only on failure
        every = np.stack(values)
        if not np.isfinite(every).all():
            for name, arr in zip(names, values, strict=True):
                if not np.isfinite(arr).all():
                    raise InputError(f"{name}: must be finite")
        if (every[[0, 2, 3]] <= 0).any() or (every[[1, 4]] < 0).any():
            for name, arr in (("heat_capacity", c), ("conductance", h), ("effusivity", e)):
                if (arr <= 0).any():
                    raise InputError(f"{name}: must be > 0")
            for name, arr in (("loss", g), ("spreading", ks)):
                if (arr < 0).any():
                    raise InputError(f"{name}: must be >= 0")
        return cls(c, g, h, e, ks, v0_, s)

    @classmethod
    def of_touched(cls, params: Mapping[str, np.ndarray]) -> ContactModel:
        """The model of the touched pixels of a draw's ``params`` (per pixel, (B, P) arrays; the
        ``touched`` mask selects the rows), heater at its set temperature (no heating step)."""
        sel = params["touched"]
        return cls.create(
            params["heat_capacity"][sel],
            params["loss"][sel],
            params["conductance"][sel],
            params["effusivity"][sel],
            params["spreading"][sel],
            params["v0"][sel],
            0.0,
        )

    @cached_property
    def poles(self) -> tuple[np.ndarray, np.ndarray]:
        """Roots ``p`` (..., 3) of D and the weights ``N(p) / D'(p)`` (..., 3), complex128.

        Nearly equal roots (relative gap < 1e-3) are split by nudging H up by 1e-6, 1e-5, ... relative
        (a double root splits like the square root of the nudge).
        """
        c, g, e, ks, v0, s = self.heat_capacity, self.loss, self.effusivity, self.spreading, self.v0, self.heating
        h = self.conductance.copy()
        coef = _cubic(c, g, h, e, ks)
        r = _roots(coef)
        for nudge in (1e-6, 1e-5, 1e-4):
            close = _min_gap(r) < 1e-3
            if not close.any():
                break
            h = np.where(close, self.conductance * (1 + nudge), h)
            coef = _cubic(c, g, h, e, ks)
            r = np.where(close[..., None], _roots(coef), r)
        coef = coef[..., None, :]
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
