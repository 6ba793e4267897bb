"""Closed-form responses of a real thermistor channel: lag, heater control, passive sensing.

A channel is a lumped body (heat capacity per area ``C``, loss ``G`` to its surroundings) that
touches a semi-infinite object through a contact conductance ``H``; the object's surface admittance
is ``Z(s) = e sqrt(s) + k_s`` (effusivity ``e``, spreading conductance ``k_s``; see
:mod:`synth.sensors.thermal`). On top of the seed's model, a real channel has:

* **thermistor lag**: the thermistor reads the body through up to two first-order poles,
  ``L(s) = 1 / ((1 + tau_1 s)(1 + tau_2 s))`` (a bead's own heat capacity behind its glue);
* **heater control**: the heater either runs open loop (constant power) or holds the *measured*
  temperature at a set point with a PI controller ``dQ = -(K_p + K_i / s) dR`` (W/m^2 per K of
  reading); before contact the channel sits at its set point (or open-loop steady state);
* **passive channels**: an unheated thermistor (no controller, its own ``C``, ``G``, ``H``, lag)
  whose pre-contact temperature is its surroundings', touching the same object.

With ``q = sqrt(s)`` and ``V0`` the channel's pre-contact temperature minus the object's, the
reading's deviation from its pre-contact value is (every quantity per unit contact area)::

    R(s) = -V0 H Z / D(q),
    D(q) = q^2 Lq(q) [(C q^2 + G)(H + Z) + H Z] + (K_p q^2 + K_i)(H + Z),   Lq = 1 / L(q^2).

``R = N(q) / (q^2 D*(q))`` with polynomials in ``q`` (a factor ``q^2`` cancels when ``K_i = 0``),
and partial fractions over the simple roots ``p`` of ``D*`` give

    r(t) = sum_p  N(p) / D*'(p) * phi(p, t),   phi(p, t) = (erfcx(-p sqrt t) - 1) / p,

the same closed form as the seed's case (:func:`synth.sensors.thermal.phi`). The same denominator
serves a heater power step ``dQ`` (numerator ``H + Z``: ``R = dQ (H + Z) / (q^2 D*)``), a reading
that drifted at ``r`` before contact (a net heating ``C r`` that goes on, plus the lag chain's own
decay of its lead ``r (tau_1 + tau_2)``) and a contact that builds up over ``ramp`` seconds (the
average of step contacts starting in ``[0, ramp]``: ``(Psi(t) - Psi(t - ramp)) / ramp`` with
``Psi`` the closed-form time integral :func:`phi_integral`): :func:`channel_terms`. A stable channel has
no pole ``s = p^2`` with ``Re s >= 0``: roots with ``Re p <= 0`` are not poles at all, and roots
with ``Re p > 0`` are poles that decay when ``|Re p| < |Im p|``. The lag's roots ``q = +-i /
sqrt(tau)`` lie on the imaginary axis, where ``erfcx`` is bounded (Faddeeva's ``w`` on the real
line), and a controller moves them a little to either side; ``phi`` stays bounded for every such
root, so the curve is finite for every ``t >= 0``. A controller whose gains make the loop unstable
has a growing pole: that is refused (:class:`~synth.errors.InputError`), not simulated. Nearly
equal lags are moved apart keeping their sum (:func:`_split_lags`: the curve moves by < 1e-4 of
itself); other nearly equal roots are split by a relative nudge of ``D*``'s constant term.
The heater is assumed never to saturate (``Q0 + dQ >= 0``), which holds for set points a few
kelvin above ambient and the drops a touch causes.

Every closed form here is checked against an independent finite-difference solution in the tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special

from synth.errors import InputError

__all__ = [
    "ChannelModel",
    "ChannelTerms",
    "NuisanceTerms",
    "channel_response",
    "channel_terms",
    "nuisance_terms",
    "phi_integral",
    "rational_response",
]

_SQRT_PI = math.sqrt(math.pi)

#: relative gap below which two roots count as a double root: partial fractions lose about
#: log10(1 / gap) digits near one, so 1e-5 still leaves ~1e-11 relative accuracy
_CLOSE = 1e-5
#: largest real part (relative to |p|) a root may have and still count as stable
_STABLE_TOL = 1e-7


def _phi(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    from synth.sensors.thermal.physics import phi  # the seed model's stable kernel, shared

    return phi(p, t)


def _poly_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched product of polynomials (..., n) and (..., m), highest power first."""
    n, m = a.shape[-1], b.shape[-1]
    out = np.zeros((*np.broadcast_shapes(a.shape[:-1], b.shape[:-1]), n + m - 1))
    for i in range(n):
        out[..., i : i + m] += a[..., i : i + 1] * b
    return out


def _poly_add(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched sum of polynomials, highest power first (the shorter one padded on the left)."""
    n = max(a.shape[-1], b.shape[-1])
    pad = [(0, 0)] * (a.ndim - 1)
    a = np.pad(a, [*pad, (n - a.shape[-1], 0)])
    b = np.pad(b, [*[(0, 0)] * (b.ndim - 1), (n - b.shape[-1], 0)])
    return a + b


def _roots(den: np.ndarray) -> np.ndarray:
    """Roots (B, n) of the polynomials ``den`` (B, n + 1), leading coefficient nonzero: the companion
    matrices' eigenvalues polished by two Newton steps (the eigen-solver's error is relative to the
    largest root)."""
    a = den[:, 1:] / den[:, :1]
    n = a.shape[1]
    comp = np.zeros((len(den), n, n))
    comp[:, 0, :] = -a
    comp[:, np.arange(1, n), np.arange(n - 1)] = 1.0
    r = np.linalg.eigvals(comp).astype(np.complex128)
    deriv = den[:, :-1] * np.arange(n, 0, -1)
    for _ in range(2):
        f = _horner(den, r)
        df = _horner(deriv, r)
        ok = np.abs(df) > 0
        r = np.where(ok, r - f / np.where(ok, df, 1.0), r)
    return r


def _horner(coef: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Polynomials ``coef`` (B, n) (highest first) at points ``x`` (B, k)."""
    out = np.zeros(x.shape, dtype=np.complex128)
    for j in range(coef.shape[1]):
        out = out * x + coef[:, j : j + 1]
    return out


def _min_gap(r: np.ndarray) -> np.ndarray:
    """Smallest pairwise root distance relative to the larger root of the pair, per row."""
    if r.shape[1] < 2:
        return np.full(len(r), np.inf)
    diff = np.abs(r[:, :, None] - r[:, None, :])
    scale = np.maximum(np.maximum(np.abs(r[:, :, None]), np.abs(r[:, None, :])), 1e-300)
    rel = diff / scale
    rel[:, np.arange(r.shape[1]), np.arange(r.shape[1])] = np.inf
    return rel.min(axis=(1, 2))


#: lags closer than twice this (relative) are moved to +-this about their mean (see _split_lags)
_LAG_SPLIT = 1e-2


def _split_lags(lag1: np.ndarray, lag2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two lags closer than 2 % moved to +-1 % about their mean. Equal lags are a double root on the
    imaginary axis, where partial fractions are singular and a root-finder is only accurate to
    ~sqrt(eps); the move keeps ``tau_1 + tau_2`` (the s coefficient of ``(1 + tau_1 s)(1 + tau_2 s)``)
    and changes ``tau_1 tau_2`` by less than 1e-4 of itself, so the curve moves by less than that."""
    both = (lag1 > 0) & (lag2 > 0)
    mean = 0.5 * (lag1 + lag2)
    close = both & (np.abs(lag1 - lag2) < 2 * _LAG_SPLIT * mean)
    return np.where(close, mean * (1 - _LAG_SPLIT), lag1), np.where(close, mean * (1 + _LAG_SPLIT), lag2)


def _poles(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Roots ``p`` (B, n) of ``den`` and the partial-fraction weights ``N(p) / D'(p)`` (B, n) of every
    numerator in ``num`` (B, m) or (K, B, m) (then (K, B, n)). Raises :class:`InputError` for a
    growing mode (see :func:`rational_response`)."""
    den = np.array(den, dtype=np.float64)
    r = _roots(den)
    # a root p is a pole of R at s = p^2 on the principal sheet only when Re p > 0; it grows when
    # Re(p^2) >= 0 as well. Roots with Re p > 0 but |Re p| < |Im p| are decaying oscillations (the
    # lag's imaginary-axis pair moved by the controller), and phi stays bounded for them.
    growing = (r.real > _STABLE_TOL * np.abs(r)) & (np.abs(r.real) >= np.abs(r.imag))
    if growing.any():
        row = int(np.argwhere(growing.any(axis=1))[0][0])
        raise InputError(
            f"unstable channel (a growing mode at s = {r[row][growing[row]][0] ** 2:.4g} 1/s): the heater "
            "controller's gains drive the reading away from its set point; lower controller_kp/controller_ki"
        )
    base = den[:, -1].copy()
    for nudge in (1e-6, 1e-5, 1e-4):
        close = _min_gap(r) < _CLOSE
        if not close.any():
            break
        den[close, -1] = base[close] * (1 + nudge)
        r[close] = _roots(den[close])
    deriv = den[:, :-1] * np.arange(den.shape[1] - 1, 0, -1)
    inv = 1.0 / _horner(deriv, r)
    nums = np.asarray(num, dtype=np.float64)
    if nums.ndim == 2:
        return r, _horner(nums, r) * inv
    return r, np.stack([_horner(n_, r) * inv for n_ in nums])


def _evaluate(r: np.ndarray, weights: np.ndarray, t: np.ndarray, integral: bool = False) -> np.ndarray:
    """``sum_p w_p phi(p, t)`` (or ``psi``: its time integral) for times ``t`` (B, T), 0 for t <= 0."""
    kernel = phi_integral if integral else _phi
    tt = np.maximum(np.asarray(t, dtype=np.float64), 0.0)
    out = np.zeros(tt.shape)
    for j in range(r.shape[1]):  # one root at a time: (B, T) temporaries, not (B, T, n)
        out += np.real(weights[:, j : j + 1] * kernel(r[:, j : j + 1], tt))
    return out


def _ramp_averaged(r: np.ndarray, weights: np.ndarray, t: np.ndarray, ramp: np.ndarray) -> np.ndarray:
    """:func:`_evaluate`'s step response averaged over step contacts starting in ``[0, ramp]`` of
    each row (B,): ``(Psi(t) - Psi(t - ramp)) / ramp``; a row with ``ramp = 0`` keeps the step."""
    step = _evaluate(r, weights, t)
    smooth = ramp > 0
    if smooth.any():
        safe = np.where(smooth, ramp, 1.0)[:, None]
        integral = _evaluate(r, weights, t, integral=True) - _evaluate(r, weights, t - safe, integral=True)
        step = np.where(smooth[:, None], integral / safe, step)
    return step


def rational_response(t: np.ndarray, num: np.ndarray, den: np.ndarray) -> np.ndarray:
    """Inverse Laplace transform of ``N(q) / (q^2 D(q))`` (``q = sqrt(s)``) at times ``t >= 0``.

    ``num`` (B, m) and ``den`` (B, n + 1) hold the polynomials' coefficients in ``q``, highest power
    first, ``m <= n``, ``den[:, 0] != 0``, ``D(0) != 0``; ``t`` is (T,) or (B, T). Returns (B, T)
    float64. Raises :class:`InputError` for a root in ``Re q > 0`` (an unstable channel).
    """
    r, weights = _poles(num, den)
    tt = np.asarray(t, dtype=np.float64)
    return _evaluate(r, weights, np.broadcast_to(tt, (len(r), tt.shape[-1])))


#: power-series coefficients of h(y) = (erfcx(y) - 1 + 2 y / sqrt(pi) - y^2) / y^3
_PSI_SERIES = np.array([(-1.0) ** n / math.gamma(n / 2 + 1) for n in range(3, 26)])
#: |y| below which psi uses its series (23 terms: truncation < 1e-17 relative there)
_PSI_RADIUS = 0.5


def phi_integral(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``psi(p, t) = int_0^t phi(p, tau) dtau = (erfcx(-p sqrt t) - 1 - 2 p sqrt(t / pi) - p^2 t) / p^3``
    (complex128), for the same ``p`` and ``t >= 0`` as :func:`synth.sensors.thermal.phi`.

    From ``d/dt erfcx(-p sqrt t) = p^2 erfcx(-p sqrt t) + p / sqrt(pi t)``. Computed as
    ``-t^1.5 h(y)``, ``y = -p sqrt t``, with ``h``'s power series for ``|y| < 0.5`` (the direct
    quotient cancels to nothing there) and ``h(0) = -1 / Gamma(5/2)`` (``psi(0, t) = 4 t^1.5 / (3 sqrt pi)``).
    """
    root_t = np.sqrt(np.maximum(np.asarray(t, dtype=np.float64), 0.0))
    y = np.asarray(p, dtype=np.complex128) * (-root_t)
    small = np.abs(y) < _PSI_RADIUS
    y_safe = np.where(small, 1.0 + 0j, y)  # the quotient only where |y| >= 0.5
    direct = (special.erfcx(y_safe) - 1.0 + 2.0 * y_safe / _SQRT_PI - y_safe * y_safe) / y_safe**3
    y_small = np.where(small, y, 0j)
    series = np.zeros_like(y)
    for coef in _PSI_SERIES[::-1]:  # Horner
        series = series * y_small + coef
    return -(root_t**3) * np.where(small, series, direct)


@dataclass(frozen=True)
class ChannelModel:
    """One channel touching one object; every field a float64 array of the batch shape (B,).

    ``lag1_s``/``lag2_s`` are the thermistor's time constants (0 = no pole), ``kp``/``ki`` the
    heater controller's gains (0 and 0 = open loop; a passive channel has neither).
    """

    heat_capacity: np.ndarray
    loss: np.ndarray
    conductance: np.ndarray
    effusivity: np.ndarray
    spreading: np.ndarray
    lag1_s: np.ndarray
    lag2_s: np.ndarray
    kp: np.ndarray
    ki: np.ndarray

    @classmethod
    def create(cls, **params: float | np.ndarray) -> ChannelModel:
        """Broadcast keyword parameters (the field names; lags and gains default to 0)."""
        defaults = {"spreading": 0.0, "lag1_s": 0.0, "lag2_s": 0.0, "kp": 0.0, "ki": 0.0}
        merged = {**defaults, **params}
        names = [f for f in cls.__dataclass_fields__]
        missing = [n for n in names if n not in merged]
        if missing:
            raise TypeError(f"ChannelModel.create: missing {', '.join(missing)}")
        arrays = np.broadcast_arrays(*(np.atleast_1d(np.asarray(merged[n], dtype=np.float64)) for n in names))
        values = dict(zip(names, (np.array(a).ravel() for a in arrays), strict=True))
        for name, arr in values.items():
            if not np.isfinite(arr).all():
                raise InputError(f"{name}: must be finite")
        for name in ("heat_capacity", "conductance", "effusivity"):
            if (values[name] <= 0).any():
                raise InputError(f"{name}: must be > 0")
        for name in ("loss", "spreading", "lag1_s", "lag2_s", "kp", "ki"):
            if (values[name] < 0).any():
                raise InputError(f"{name}: must be >= 0")
        return cls(**values)

    def __len__(self) -> int:
        return len(self.heat_capacity)

    def _rows(self, index: np.ndarray) -> ChannelModel:
        return ChannelModel(**{n: getattr(self, n)[index] for n in self.__dataclass_fields__})

    def polynomials(self) -> tuple[np.ndarray, np.ndarray]:
        """``(N, D*)`` per unit ``V0`` for rows sharing one structure (see the module docstring)."""
        num, _, den = self._polynomials()
        return num, den

    def _polynomials(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(N_object, N_power, D*)``: the numerators per unit ``V0`` and per unit power step."""
        b = len(self)
        c, g, h = self.heat_capacity, self.loss, self.conductance
        z = np.stack([self.effusivity, self.spreading], axis=1)  # e q + k_s
        hz = np.stack([self.effusivity, h + self.spreading], axis=1)  # H + Z
        lq = np.ones((b, 1))
        lag1, lag2 = _split_lags(self.lag1_s, self.lag2_s)
        for tau in (lag1, lag2):
            if (tau > 0).all():
                lq = _poly_mul(lq, np.stack([tau, np.zeros(b), np.ones(b)], axis=1))
        body = _poly_add(_poly_mul(np.stack([c, np.zeros(b), g], axis=1), hz), h[:, None] * z)
        lag_body = _poly_mul(lq, body)
        num = -h[:, None] * z
        power = hz  # a heater power step dQ: R = dQ (H + Z) / D
        if (self.ki > 0).all():
            loop = _poly_mul(np.stack([self.kp, np.zeros(b), self.ki], axis=1), hz)
            den = _poly_add(_poly_mul(lag_body, np.array([[1.0, 0.0, 0.0]])), loop)
            num = _poly_mul(num, np.array([[1.0, 0.0, 0.0]]))  # R = N q^2 / (q^2 D*)
            power = _poly_mul(power, np.array([[1.0, 0.0, 0.0]]))
        elif (self.kp > 0).all():
            den = _poly_add(lag_body, self.kp[:, None] * hz)
        else:
            den = lag_body
        return num, power, den

    def structure(self) -> np.ndarray:
        """Per-row structure code: which poles and gains are present (rows of one code batch)."""
        return (
            (self.lag1_s > 0).astype(np.int64)
            + 2 * (self.lag2_s > 0)
            + 4 * (self.kp > 0)
            + 8 * (self.ki > 0)
            + 16 * (self.spreading > 0)
        )

    def response(self, t: np.ndarray) -> np.ndarray:
        """Reading deviation per kelvin of ``V0`` (the curve for ``V0 = 1 K``: it falls from 0), (B, T)
        at times ``t >= 0`` after contact ((T,) or (B, T)); see :func:`channel_response`."""
        tt = np.asarray(t, dtype=np.float64)
        tt = np.broadcast_to(tt, (len(self), tt.shape[-1]))
        out = np.empty(tt.shape)
        codes = self.structure()
        for code in np.unique(codes):
            rows = np.flatnonzero(codes == code)
            num, den = self._rows(rows).polynomials()
            out[rows] = rational_response(tt[rows], num, den)
        return out


@dataclass(frozen=True)
class ChannelTerms:
    """The basis curves of a channel's reading, (B, T) each, at times ``t`` relative to the contact
    onset (see :func:`channel_terms`). A reading is ``R0 + drift_k_s * drift + v0 * obj + sum_k dQ_k *
    power(t - t_k)``: linear in the temperatures, the drift and the heater's power steps."""

    obj: np.ndarray
    drift: np.ndarray
    power: np.ndarray | None


def _lag_offsets(t: np.ndarray, lag1: np.ndarray, lag2: np.ndarray) -> np.ndarray:
    """The reading minus the body temperature for a body that ramped at 1 K/s until ``t = 0`` and
    then stopped: ``-(tau_1 + tau_2)`` before, decaying after (the lag chain's own free response)."""
    t1, t2 = _split_lags(lag1, lag2)
    t1, t2 = np.where(t1 > 0, t1, t2), np.where(t1 > 0, t2, 0.0)  # a lone pole is t1
    tt = np.maximum(t, 0.0)
    first = -t1[:, None] * np.exp(-tt / np.where(t1 > 0, t1, 1.0)[:, None])
    # x2' = (x1 - x2) / t2 from x2(0) = -(t1 + t2) with x1 = -t1 exp(-t/t1): t1 != t2 (split apart)
    two = t2 > 0
    k = np.where(two, -t1 * t1 / np.where(two, t1 - t2, 1.0), 0.0)[:, None]
    decay2 = np.exp(-tt / np.where(two, t2, 1.0)[:, None])
    second = k * np.exp(-tt / np.where(t1 > 0, t1, 1.0)[:, None]) + (-(t1 + t2)[:, None] - k) * decay2
    after = np.where(two[:, None], second, np.where((t1 > 0)[:, None], first, 0.0))
    return np.where(t > 0, after, -(t1 + t2)[:, None])


def _rows_of_times(t: np.ndarray, ramp_s: float | np.ndarray, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Sample times ``t`` ((T,) or (rows, T)) and contact build-up times ``ramp_s`` (scalar or
    (rows,)) as one row per touch, float64; a negative or non-finite build-up is refused."""
    tt = np.asarray(t, dtype=np.float64)
    tt = np.broadcast_to(tt, (rows, tt.shape[-1]))
    ramp = np.broadcast_to(np.asarray(ramp_s, dtype=np.float64), (rows,))
    if (ramp < 0).any() or not np.isfinite(ramp).all():
        raise InputError("ramp_s: must be finite and >= 0")
    return tt, ramp


def channel_terms(
    model: ChannelModel, t: np.ndarray, ramp_s: np.ndarray | float = 0.0, t_power: np.ndarray | None = None
) -> ChannelTerms:
    """Basis curves of ``model``'s reading at times ``t`` (B, T) after the contact onset (negative
    before it).

    - ``obj``: per kelvin of ``V0`` (the channel's body temperature at onset minus the object's),
      with the contact building up uniformly over ``ramp_s`` (B,) seconds after the onset (the
      average of step contacts starting in ``[0, ramp_s]``: ``(Psi(t) - Psi(t - ramp)) / ramp`` with
      the closed-form time integral :func:`phi_integral`; ``ramp_s = 0``: a step);
    - ``drift``: per K/s of a pre-contact drift of the reading (a body heated by a net ``S = C r``):
      ``t`` before the onset, then ``S`` keeps heating through the contact while the lag's lead
      decays (an open-loop channel: with a controller the channel must be at rest before contact);
    - ``power``: per W/m^2 of a heater power step at ``t_power`` (B,) seconds after the onset (the
      contact still holding), or ``None``.

    Before the onset ``obj`` and ``power`` are 0, so a whole record is one formula.
    """
    b = len(model)
    tt, ramp = _rows_of_times(t, ramp_s, b)
    obj = np.empty(tt.shape)
    drift = np.empty(tt.shape)
    power = None if t_power is None else np.empty(tt.shape)
    codes = model.structure()
    for code in np.unique(codes):
        rows = np.flatnonzero(codes == code)
        part = model._rows(rows)
        num, num_power, den = part._polynomials()
        r, (w_obj, w_power) = _poles(np.stack([num, _pad_to(num_power, num.shape[1])]), den)
        t_r, ramp_r = tt[rows], ramp[rows]
        obj[rows] = _ramp_averaged(r, w_obj, t_r, ramp_r)
        if ((part.kp > 0) | (part.ki > 0)).any():
            drift[rows] = np.where(t_r > 0, np.nan, t_r)  # undefined: a controlled channel rests before contact
        else:
            heating = part.heat_capacity[:, None] * _evaluate(r, w_power, t_r)
            # the reading lags the ramping body by tau_1 + tau_2; after the onset that lead decays
            lead = (part.lag1_s + part.lag2_s)[:, None]
            offsets = _lag_offsets(t_r, part.lag1_s, part.lag2_s)
            drift[rows] = np.where(t_r > 0, heating + offsets + lead, t_r)
        if power is not None and t_power is not None:
            delay = np.broadcast_to(np.asarray(t_power, dtype=np.float64), (b,))[rows]
            power[rows] = _evaluate(r, w_power, t_r - delay[:, None])
    return ChannelTerms(obj=obj, drift=drift, power=power)


def _pad_to(poly: np.ndarray, width: int) -> np.ndarray:
    """``poly`` (B, m) padded on the left with zero coefficients to (B, width)."""
    return np.pad(poly, [(0, 0), (width - poly.shape[1], 0)]) if poly.shape[1] < width else poly


def channel_response(model: ChannelModel, v0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Reading minus its pre-contact value, (B, T), ``t`` seconds after contact (0 before it).

    ``v0`` (B,): the channel's pre-contact temperature minus the object's (K). Linear in ``v0``.
    """
    tt = np.asarray(t, dtype=np.float64)
    curve = model.response(np.maximum(tt, 0.0))
    return np.where(np.broadcast_to(tt, curve.shape) > 0, curve, 0.0) * np.asarray(v0, dtype=np.float64)[:, None]


@dataclass(frozen=True)
class NuisanceTerms:
    """Extra basis curves of a channel's reading, (B, T) each (see :func:`nuisance_terms`)."""

    #: per W/m^2 of a constant flux out of the object into the contact from the onset on
    flux: np.ndarray
    #: per W/m^2 of a heater power step at each of the given times, (K, B, T)
    steps: np.ndarray
    #: per kelvin of ``V0``: a contact that builds up uniformly over the ``precursor_s`` seconds
    #: before the onset minus the one at the onset (see :func:`nuisance_terms`), or None
    precursor: np.ndarray | None = None


def nuisance_terms(
    model: ChannelModel,
    t: np.ndarray,
    ramp_s: np.ndarray | float = 0.0,
    t_steps: tuple[np.ndarray, ...] = (),
    precursor_s: float = 0.0,
) -> NuisanceTerms:
    """Basis curves for what differs from touch to touch beyond the object's temperature, at times
    ``t`` (B, T) after the contact onset:

    - ``flux``: an object whose temperature is not uniform with depth. Its initial profile
      ``T_obj + g x`` (a cooled block warming from its surface, a block in a draught) is a steady
      solution of the heat equation that carries ``F = k g`` to the surface; in contact the sensor
      sees ``H (T_b - T_i) = Z (T_i - T_obj) - F``, so the body's reading moves by
      ``F H / (q^2 D*)`` (the object's term with ``H`` in place of ``-H Z``), the contact building
      up over ``ramp_s`` as in :func:`channel_terms`;
    - ``steps``: a heater power step at each time of ``t_steps`` (B,) after the onset (a heater that
      changes its power more than once: a controller's response, read as steps), as
      :func:`channel_terms`' ``power``.

    - ``precursor`` (``precursor_s > 0``): part of the contact arrives early. A pad that closes
      unevenly (tilt, curvature, roughness), or an air gap that conducts as it thins, exchanges heat
      with the object before the force rises; as a fraction ``eps`` of the contact building up
      uniformly over the ``precursor_s`` seconds before the onset, the reading is ``V0 ((1 - eps) obj
      + eps obj_early)``: this column is ``obj_early - obj`` (amplitude ``eps V0``), both the same
      closed form as :func:`channel_terms`' ``obj`` (a ramp-averaged contact).

    All are 0 before their start, linear in their amplitude, and closed forms (checked against a
    finite-volume solution in the tests).
    """
    if not (np.isfinite(precursor_s) and precursor_s >= 0):
        raise InputError("precursor_s: must be finite and >= 0")
    b = len(model)
    tt, ramp = _rows_of_times(t, ramp_s, b)
    flux = np.empty(tt.shape)
    steps = np.empty((len(t_steps), *tt.shape))
    precursor = np.empty(tt.shape) if precursor_s > 0 else None
    codes = model.structure()
    for code in np.unique(codes):
        rows = np.flatnonzero(codes == code)
        part = model._rows(rows)
        num_obj, num_power, den = part._polynomials()
        num_flux = part.conductance[:, None]
        if (part.ki > 0).all():  # R = N q^2 / (q^2 D*) with an integrating controller
            num_flux = _poly_mul(num_flux, np.array([[1.0, 0.0, 0.0]]))
        width = den.shape[1] - 1
        r, (w_flux, w_power, w_obj) = _poles(
            np.stack([_pad_to(num_flux, width), _pad_to(num_power, width), _pad_to(num_obj, width)]), den
        )
        t_r, ramp_r = tt[rows], ramp[rows]
        flux[rows] = _ramp_averaged(r, w_flux, t_r, ramp_r)
        if precursor is not None:
            early = _ramp_averaged(r, w_obj, t_r + precursor_s, np.full(len(rows), precursor_s))
            precursor[rows] = early - _ramp_averaged(r, w_obj, t_r, ramp_r)
        for k, delay in enumerate(t_steps):
            d = np.broadcast_to(np.asarray(delay, dtype=np.float64), (b,))[rows]
            steps[k, rows] = _evaluate(r, w_power, t_r - d[:, None])
    return NuisanceTerms(flux=flux, steps=steps, precursor=precursor)
