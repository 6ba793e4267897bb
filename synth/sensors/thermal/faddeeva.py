"""``erfcx`` of complex arguments in the closed right half-plane, vectorised in numpy.

The fast record path (:mod:`synth.sensors.thermal.fast`) needs ``erfcx(y)`` at ``y = -p sqrt(t)``
for the complex roots ``p`` of metals' contacts (``Re p < 0``, so ``Re y >= 0``): about 400
values per touch of the ``thermal`` scene, where scipy's compiled Faddeeva routine costs ~120-180
ns a value (a third of the simulator's time). :func:`erfcx_right` evaluates the same function with
Weideman's rational series (J. A. C. Weideman, "Computation of the complex error function", SIAM
J. Numer. Anal. 31 (1994) 1497-1518): with ``erfcx(y) = w(i y)`` and ``w`` the Faddeeva function,

    w(zeta) = 2 P(Z) / (L - i zeta)^2 + 1 / (sqrt(pi) (L - i zeta)),   Z = (L + i zeta) / (L - i zeta),

for ``Im zeta >= 0`` (here ``zeta = i y``, so ``L - i zeta = L + y``, ``Z = (L - y) / (L + y)``),
``P`` a polynomial of degree ``N - 1`` whose coefficients are the Fourier coefficients of
``(L^2 + t^2) exp(-t^2)`` at ``t = L tan(theta / 2)`` (an FFT, once at import). The map takes the
half-plane onto the unit disk (``|Z| <= 1``), so Horner's rule on ``P`` is stable: ~40 complex
multiply-adds a value, ~30-40 ns in numpy against scipy's ~120-180 ns.

Accuracy (``N = 40``, ``L = sqrt(N / sqrt 2)``, the paper's choice): against 30-digit mpmath,
at most ~1.5e-15 relative over the right half-plane (``|y|`` from 0 to 1e4, arguments from -90 to
+90 degrees, sampled); scipy's own ``erfcx`` is off by up to ~3e-14 there (near the imaginary axis
at ``|y| ~ 10``). The two agree to ~3e-14 relative everywhere in that region
(``tests/synth/sensors/test_thermal_faddeeva.py``). Arguments with ``Re y < 0`` (the formula's
``w`` would be in the lower half-plane, where it does not hold) or non-finite ones go to scipy.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

__all__ = ["erfcx_minus_one_real", "erfcx_right"]

#: terms of Weideman's polynomial (N = 36 already reaches ~5e-15 with a tuned L; 40 with the
#: paper's L reaches ~1e-15 for ~10 % more work)
_TERMS = 40
_L = math.sqrt(_TERMS / math.sqrt(2.0))
#: values per pass: the (complex) temporaries of a chunk stay in the L2 cache
_CHUNK = 16_384
_INV_SQRT_PI = 1.0 / math.sqrt(math.pi)
#: |y| from which scipy takes over (1 / (L + y)^2 underflows near 1e154)
_LARGE = 1e100


def _weideman_coefficients(n_terms: int, scale: float) -> np.ndarray:
    """Coefficients ``a_N .. a_1`` (highest power first) of Weideman's polynomial ``P``: the
    Fourier coefficients of ``(L^2 + t^2) exp(-t^2)``, ``t = L tan(theta / 2)``, on ``4 N`` points."""
    m = 2 * n_terms
    k = np.arange(-m + 1, m)
    t = scale * np.tan(k * np.pi / (2 * m))
    samples = np.concatenate([[0.0], np.exp(-t * t) * (scale * scale + t * t)])
    fourier = np.fft.fft(np.fft.fftshift(samples)).real / (2 * m)
    return fourier[1 : n_terms + 1][::-1].copy()


_COEF = _weideman_coefficients(_TERMS, _L)


def _weideman(y: np.ndarray, out: np.ndarray) -> None:
    """``erfcx(y)`` by the rational series into ``out`` (complex, ``y``'s shape, ``Re y >= 0``)."""
    inv = np.add(y, _L)
    np.divide(1.0, inv, out=inv)  # 1 / (L + y): one complex division, products from here on
    z = np.subtract(_L, y)
    z *= inv  # Z = (L - y) / (L + y), |Z| <= 1
    acc = np.multiply(z, _COEF[0], out=out)
    acc += _COEF[1]
    for coef in _COEF[2:]:
        acc *= z
        acc += coef
    acc *= 2.0
    acc *= inv
    acc += _INV_SQRT_PI
    acc *= inv


def _erfcx_into(y: np.ndarray, out: np.ndarray) -> None:
    """``erfcx(y)`` into ``out``: the rational series, or scipy where it does not hold."""
    with np.errstate(invalid="ignore", over="ignore"):  # NaN/inf inputs: replaced below
        _weideman(y, out)
    if y.size == 0:
        return
    # the formula holds in the right half-plane only; NaN, inf and |y| >= 1e100 (where 1/(L + y)^2
    # would underflow) get scipy's answer (no such argument occurs in the simulator). Reductions
    # first (NaN fails them): the usual chunk needs no mask
    if y.real.min() >= 0 and max(np.abs(y.real).max(), np.abs(y.imag).max()) < _LARGE:
        return
    other = ~(y.real >= 0) | ~(np.abs(y) < _LARGE)
    out[other] = special.erfcx(y[other])


def erfcx_right(y: np.ndarray) -> np.ndarray:
    """``scipy.special.erfcx(y)`` for complex ``y`` (any shape), to ~1e-15 relative where
    ``Re y >= 0`` (see the module docstring); other values are passed to scipy."""
    y = np.asarray(y, dtype=np.complex128)
    flat = y.reshape(-1)
    out = np.empty(flat.shape, dtype=np.complex128)
    for start in range(0, len(flat), _CHUNK):
        _erfcx_into(flat[start : start + _CHUNK], out[start : start + _CHUNK])
    return out.reshape(y.shape)


def erfcx_minus_one_real(y: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """``Re(weight (erfcx(y) - 1))`` (rows, n) for complex ``y`` (rows, n) and a complex weight per
    row (rows,): :func:`erfcx_right` with the weighting done while a chunk of rows is in cache."""
    y = np.asarray(y, dtype=np.complex128)
    weight = np.asarray(weight, dtype=np.complex128)
    if y.ndim != 2 or weight.shape != y.shape[:1]:
        raise ValueError(f"expected y (rows, n) and weight (rows,), got {y.shape} and {weight.shape}")
    result = np.empty(y.shape)
    step = max(1, _CHUNK // max(1, y.shape[1]))
    scratch = np.empty((min(step, len(y)), y.shape[1]), dtype=np.complex128)
    for start in range(0, len(y), step):
        part = scratch[: len(y[start : start + step])]
        _erfcx_into(y[start : start + step], part)
        part -= 1.0
        part *= weight[start : start + step, None]
        result[start : start + step] = part.real
    return result
