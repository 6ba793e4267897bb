"""Fast whole-record curves of the seed's thermal model: only the samples that need the closed form.

:func:`synth.sensors.thermal.touch_excess` (the reference) evaluates the contact solution
``v = V0 + sum_i w_i phi(p_i, t)`` (three complex ``erfcx`` per sample) on every sample of the
record and then masks most of it away. A profile of the ``thermal`` scene (16 pixels, 325 samples)
put 85 % of the simulator's time in :func:`~synth.sensors.thermal.phi`. :func:`record_excess`
gives the same curve (to ~1e-12 K) from far less work:

* **nothing before onset**: a pixel reads ``V0`` there by definition; **nothing after release**
  but the closed-form recovery (one exponential per sample) from the value at release;
* the contact samples of every pixel are gathered into a short per-pixel grid (``t - onset``, the
  pixel's own sample times), so the work is (pixels in contact) x (contact samples);
* **no complex erfcx for slow roots**: ``phi(p, t) = sqrt(t) g(-p sqrt t)`` with ``g`` entire
  (:data:`~synth.sensors.thermal._G_SERIES`). For every root whose ``|p| sqrt(t)`` stays below
  :data:`SERIES_RADIUS` over the pixel's contact, the weighted sum over those roots folds into
  one *real* power series in ``sqrt(t)`` per pixel (coefficients ``a_m Re sum_i w_i (-p_i)^m``),
  evaluated by Horner on the pixel's grid: a few multiply-adds per sample instead of two complex
  ``erfcx``. In the seed's sensor the complex pair is the pixel's own slow mode (``|p| ~
  sqrt(G / C) ~ 0.35 s^-1/2``), so the pair always takes this path;
* **real roots** (the fast interface mode, ``p`` of -10 to -2000 s^-1/2) take the *real* ``erfcx``
  (about 6x cheaper than the complex one) on every sample: near ``y = 0`` ``erfcx(y) - 1`` loses
  relative accuracy only, its absolute error (~1e-16 ``|w / p|`` K) is what the curve sees;
* anything else (a complex root with a large ``|p| sqrt t``, a metal's pair) takes the complex
  ``erfcx``, once per conjugate pair, by :func:`~synth.sensors.thermal.faddeeva.erfcx_right`
  (Weideman's rational series in numpy, ~30 ns a value against scipy's ~120-180 ns; scipy's
  values to ~3e-14 relative, the mathematical function to ~1e-15).

Everything stays float64: the series is truncated where its next term is below 1e-17 of ``g``,
so the curve differs from the reference only by rounding (the test bounds it at 1e-9 K), and
readings after noise and the 0.01 K ADC are byte-identical in practice (checked in the tests on
the shipped scenes). float32 was measured for the Horner step: it saves little (the step is a
small share of the time) and moves the ADC's rounding, so it is not used.

What is left (``thermal`` scene, 1024-touch chunks, shares of a profile on the shared 2-core
machine, ~200 us of CPU per touch in all): the readout's normal draws, a third (5,200 per touch at
~14 ns: numpy's generator, kept so that the bytes are the reference's); the real ``erfcx`` (~1,250
values per touch), the complex one (~400 values, Weideman) and the folded series (Horner, 19-37
terms on the series pixels' samples), about a tenth each; the roots and weights (closed form), the
gathers and scatters of the per-pixel grids, the recovery and Python's per-block overhead the rest.
Blocks are large (512 pixels here, ~250 touches in :class:`~synth.sensors.thermal.ThermalModel`)
because at ~150 numpy calls per block the calls' own cost is not small. Measured and not kept:
the series' Horner in a transposed (samples, pixels) layout (slower: the per-row coefficient is
a broadcast add either way), filling only the untouched pixels' steady state (no difference).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

from synth.sensors.thermal.faddeeva import erfcx_minus_one_real
from synth.sensors.thermal.physics import _G_SERIES, _SERIES_RADIUS, ContactModel

__all__ = ["SERIES_RADIUS", "record_excess", "series_terms"]

#: largest ``|p| sqrt(t)`` a root may reach and still be summed as a power series (terms of
#: ``g`` fall like ``|y|^m / Gamma(m/2 + 1)``: at |y| = 1, 36 terms reach 1e-17, with no
#: cancellation worse than e^(|y|^2) ~ 3)
SERIES_RADIUS = 1.0
#: rows are grouped by the largest ``|y|`` their series reaches: fewer terms for the smaller
_REACH_BINS = (0.25, 0.5, 0.75, SERIES_RADIUS)
#: enough series terms for ``|y| <= SERIES_RADIUS``
_MAX_TERMS = 40
_SERIES_A = np.array([(-1.0) ** m / math.gamma((m + 1) / 2 + 1) for m in range(_MAX_TERMS)])


def series_terms(y_max: float) -> int:
    """Terms of ``g``'s series that bring its truncation below 1e-17 for ``|y| <= y_max``."""
    if y_max <= 0:
        return 1
    for m in range(1, _MAX_TERMS):
        if y_max**m / math.gamma((m + 1) / 2 + 1) < 1e-17:
            return m
    return _MAX_TERMS


def _g_series(y: np.ndarray) -> np.ndarray:
    """``g(y) = (1 - erfcx(y)) / y`` by its power series (``|y| < _SERIES_RADIUS``: the quotient
    cancels there)."""
    acc = np.zeros_like(y)
    for coef in _G_SERIES[::-1]:
        acc = acc * y + coef
    return acc


def _root_part(p: np.ndarray, w: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``Re(w phi(p, s^2))`` (rows, samples) for one root per row: real ``p <= 0`` with real ``w``,
    or complex ``p`` (``Re p < 0``) with complex ``w``, at ``s = sqrt(tau) >= 0``.

    ``phi = (erfcx(y) - 1) / p`` with ``y = -p s``: the reference's ``s (1 - erfcx(y)) / y`` is the
    same number (to rounding), and dividing the row's weight by ``p`` once replaces a division by
    ``y`` and a product with ``s`` per sample (a complex division is ~4x a product). The
    ``erfcx`` is evaluated on every sample (``|p| sqrt(tau)`` of these roots exceeds
    :data:`SERIES_RADIUS`: a gather of the few small ones would cost more than it saves); near
    ``y = 0`` only the relative accuracy of ``erfcx(y) - 1`` suffers, the absolute one (what the
    curve needs) stays ~1e-16 ``|w / p|``. The complex roots' ``|y| < 0.1`` (at most the first
    sample after the onset, and the padding) still take ``g``'s series, as in ``phi``.
    """
    size = np.abs(p)
    wp = w / p  # p != 0: a root at 0 reaches 0, so it is always summed by the series
    if not np.iscomplexobj(p):
        # erfcx(0) = 1 exactly, and near y = 0 the difference erfcx(y) - 1 ~ -2 y / sqrt(pi) loses
        # relative, not absolute accuracy: |w / p| 1e-16 K at most, so no series is needed here
        excess = np.multiply(s, -p[:, None])
        special.erfcx(excess, out=excess)
        excess -= 1.0
        excess *= wp[:, None]
        return excess
    # y = -p s by its real and imaginary halves (a complex p times a real s would first cast s)
    y = np.empty(s.shape, dtype=np.complex128)
    np.multiply(s, -p.real[:, None], out=y.real)
    np.multiply(s, -p.imag[:, None], out=y.imag)
    excess = erfcx_minus_one_real(y, wp)
    # |y| < 0.1 (the first sample after an onset at most, and the padding's s = 0, where phi = 0):
    # the series of g, as in phi (erfcx_right(0) is 1 only to rounding)
    small = np.flatnonzero(s < (_SERIES_RADIUS / size)[:, None])
    if len(small):
        rows = small // s.shape[1]
        flat_s = s.reshape(-1)[small]
        excess.reshape(-1)[small] = _real_part(w[rows], _g_series(y.reshape(-1)[small])) * flat_s
    return excess


def _real_part(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``Re(a b)`` of a per-row factor ``a`` (rows,) and ``b`` (rows, ...) or (n,), without the
    complex product's imaginary half."""
    a2 = a[:, None] if b.ndim == 2 else a
    if np.iscomplexobj(a2):
        return a2.real * b.real - a2.imag * b.imag
    return a2 * b.real if np.iscomplexobj(b) else a2 * b


#: terms for each reach bin (series_terms is a Python loop: once here, not per block)
_BIN_TERMS = {high: series_terms(high) for high in _REACH_BINS}

#: pixels per block of :func:`record_excess`: its temporaries (pixels x samples) stay in cache
_BLOCK_ROWS = 512


def _contact_block(r: np.ndarray, w: np.ndarray, tau: np.ndarray, tau_max: np.ndarray) -> np.ndarray:
    s = np.sqrt(tau)
    size = np.abs(r)
    reach = size * np.sqrt(tau_max)[:, None]  # largest |y| = |p| sqrt(tau) each root reaches
    series = reach <= SERIES_RADIUS
    total = np.zeros(tau.shape)
    if series.any():
        row_reach = np.where(series, reach, 0.0).max(axis=1)
        n_terms = series_terms(float(row_reach.max()))
        # real coefficients of the folded series: b_m = a_m Re sum_(series roots) w (-p)^m, over
        # the series roots only (about half of them), grouped by row (nonzero is row-major)
        row_of, root_of = np.nonzero(series)
        powers = np.empty((len(row_of), n_terms), dtype=np.complex128)
        powers[:, 0] = 1.0
        powers[:, 1:] = -r[row_of, root_of, None]
        np.cumprod(powers, axis=1, out=powers)
        ws = w[row_of, root_of, None]
        parts = ws.real * powers.real - ws.imag * powers.imag  # Re(w (-p)^m)
        starts = np.flatnonzero(np.r_[True, row_of[1:] != row_of[:-1]])
        coef = np.zeros((n_terms, len(r)))
        coef[:, row_of[starts]] = (_SERIES_A[:n_terms] * np.add.reduceat(parts, starts, axis=0)).T
        low = -1.0  # a root at 0 (the seed's G = k_s = 0) reaches 0
        for high in _REACH_BINS:  # rows that reach less need fewer terms
            rows = np.flatnonzero(series.any(axis=1) & (row_reach > low) & (row_reach <= high))
            low = high
            if not len(rows):
                continue
            sr = s[rows]
            terms = min(n_terms, _BIN_TERMS[high])
            # the rows' coefficients gathered once (a gather per term cost as much as the Horner step)
            row_coef = coef[:terms, rows, None]
            acc = np.broadcast_to(row_coef[terms - 1], sr.shape).copy()
            for m in range(terms - 2, -1, -1):
                acc *= sr
                acc += row_coef[m]
            acc *= sr
            total[rows] = acc  # the bins' rows are disjoint and total is 0 there: no gather and add
    # a complex root's conjugate (the cubic's coefficients are real) carries the conjugate weight
    # (exactly: the same arithmetic on conjugate inputs): Re(w phi) of the pair is twice the one's
    conj = np.conj(r)
    paired = ((r[:, :, None] == conj[:, None, :]) & (w[:, :, None] == np.conj(w)[:, None, :])).any(axis=2)
    paired &= r.imag != 0
    for j in range(r.shape[1]):
        real = ~series[:, j] & (r[:, j].imag == 0)
        other = ~series[:, j] & ~real & ~(paired[:, j] & (r[:, j].imag < 0))
        for chosen, is_real in ((real, True), (other, False)):
            if not chosen.any():
                continue
            every = bool(chosen.all())  # the common case: a slice, not a gather and a scatter
            pick: slice | np.ndarray = slice(None) if every else np.flatnonzero(chosen)
            p = r[pick, j]
            wj = w[pick, j] * np.where(paired[pick, j], 2.0, 1.0)
            total[pick] += _root_part(p.real if is_real else p, wj.real if is_real else wj, s[pick])
    return total


def _recovery(
    dt: np.ndarray, v_release: np.ndarray, source: np.ndarray, cap: np.ndarray, loss: np.ndarray
) -> np.ndarray:
    """:func:`~synth.sensors.thermal.physics.recovery_excess` (rows, samples) for per-row ``v_release``,
    ``P``, ``C``, ``G``: ``v = v_r - (P / G - v_r) expm1(-G dt / C)`` (the same number: ``phi1(x) x =
    -expm1(-x)``), four passes over the samples instead of a dozen; ``G = 0`` (the seed's model)
    rows rise linearly, ``v_r + P dt / C``."""
    held = loss > 0
    rate = loss / cap
    # per-row factor (P - G v_r) / G; 0 where G = 0 (those rows get their linear rise below)
    factor = np.divide(source - loss * v_release, loss, out=np.zeros_like(loss), where=held)
    rec = np.multiply(dt, -rate[:, None])
    np.expm1(rec, out=rec)
    rec *= -factor[:, None]
    rec += v_release[:, None]
    if not held.all():
        still = np.flatnonzero(~held)
        rec[still] += dt[still] * (source[still] / cap[still])[:, None]
    return rec


def record_excess(time_s: np.ndarray, model: ContactModel, onset: np.ndarray, release: np.ndarray) -> np.ndarray:
    """The whole-record excess (B, R) of :func:`~synth.sensors.thermal.touch_excess` (float64) for
    a flat batch ``model`` (B,) at the record's sample times ``time_s`` (R,), increasing: ``V0``
    up to the onset, the contact solution until the release, then the recovery."""
    time_s = np.asarray(time_s, dtype=np.float64)
    onset = np.asarray(onset, dtype=np.float64).reshape(-1)
    release = np.maximum(np.asarray(release, dtype=np.float64).reshape(-1), onset)
    r, w = (x.reshape(-1, 3) for x in model.poles)
    v0 = model.v0.reshape(-1)
    # what the recovery after release needs: the net heating P = S + G V0, C and G
    source = (model.heating + model.loss * model.v0).reshape(-1)
    cap, loss = model.heat_capacity.reshape(-1), model.loss.reshape(-1)
    out = np.empty((len(onset), len(time_s)))
    # pixels in order of their contact's length: a block's grid is padded to its longest contact
    by_length = np.argsort(np.searchsorted(time_s, release) - np.searchsorted(time_s, onset), kind="stable")
    for start in range(0, len(onset), _BLOCK_ROWS):
        rows = by_length[start : start + _BLOCK_ROWS]
        out[rows] = _record_block(
            time_s, r[rows], w[rows], v0[rows], onset[rows], release[rows], source[rows], cap[rows], loss[rows]
        )
    return out


def _record_block(
    time_s: np.ndarray,
    r: np.ndarray,
    w: np.ndarray,
    v0: np.ndarray,
    onset: np.ndarray,
    release: np.ndarray,
    source: np.ndarray,
    cap: np.ndarray,
    loss: np.ndarray,
) -> np.ndarray:
    b, n_t = len(onset), len(time_s)
    first = np.searchsorted(time_s, onset, side="right")  # first sample after the onset
    stop = np.searchsorted(time_s, release, side="left")  # first sample at or after the release
    n_contact = np.maximum(stop - first, 0)
    padded_t = np.concatenate([time_s, np.zeros(1)])
    # per-pixel contact grid (its own samples, t - onset), plus the release (the recovery's start)
    cols = np.arange(int(n_contact.max(initial=0)))
    idx = first[:, None] + cols[None, :]
    inside = cols[None, :] < n_contact[:, None]
    tau = np.empty((b, len(cols) + 1))
    np.subtract(padded_t[np.minimum(idx, n_t)], onset[:, None], out=tau[:, :-1])
    tau[:, :-1][~inside] = 0.0
    tau[:, -1] = release - onset
    curve = _contact_block(r, w, tau, release - onset)
    curve += v0[:, None]
    buffer = np.empty((b, n_t + 1))  # the last column takes the padding's writes
    buffer[:, :n_t] = v0[:, None]
    # scatters through the flat buffer (put_along_axis builds broadcast index tuples: ~2x the cost)
    flat = buffer.reshape(-1)
    row_start = np.arange(b)[:, None] * (n_t + 1)
    flat[row_start + np.where(inside, idx, n_t)] = curve[:, :-1]
    after = n_t - stop
    if after.max(initial=0) > 0:
        cols_r = np.arange(int(after.max()))
        idx_r = stop[:, None] + cols_r[None, :]
        valid = cols_r[None, :] < after[:, None]
        dt = padded_t[np.minimum(idx_r, n_t)] - release[:, None]
        dt[~valid] = 0.0
        rec = _recovery(dt, curve[:, -1], source, cap, loss)
        flat[row_start + np.where(valid, idx_r, n_t)] = rec
    return buffer[:, :n_t]
