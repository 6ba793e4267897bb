"""Test-only reference solver for a thermistor channel: finite volumes in the object, time by Radau.

Independent of the closed forms in ``synth.sensors.thermal_dynamics``: the object is discretised
on a geometrically graded grid (a 1-D slab, or a spherical cavity of radius ``k / k_s`` whose
surface admittance is exactly ``e sqrt(s) + k_s``); the sensor node, the thermistor's lag states
and the controller's integral are extra states of one linear system ``y' = A y + b``, ``y(0) = 0``
(deviations from the pre-contact equilibrium), integrated by a stiff implicit solver with tight tolerances.

:func:`numerical_excess` is the same kind of check for the seed's model (no lags, no control), exact
in time: it checks the analytic contact solution of ``synth.sensors.thermal.physics``.
"""

from __future__ import annotations

import numpy as np
from scipy import integrate, linalg, sparse

from synth.materials import get_material
from synth.sensors.thermal.dynamics import ChannelModel


def add_conduction_chain(matrix: np.ndarray, first_row: int, links: np.ndarray, cap: np.ndarray) -> None:
    """Conduction between consecutive cells (rows ``first_row ..``; ``links[i]`` joins cell ``i``
    to ``i + 1``, ``cap`` the cells' heat capacities) added to the rate matrix ``matrix``; the
    ends' boundaries are the caller's."""
    for i in range(len(cap)):
        row = first_row + i
        if i > 0:
            matrix[row, row - 1] += links[i - 1] / cap[i]
            matrix[row, row] -= links[i - 1] / cap[i]
        if i < len(cap) - 1:
            matrix[row, row + 1] += links[i] / cap[i]
            matrix[row, row] -= links[i] / cap[i]


def add_lag_chain(matrix: np.ndarray, first_row: int, lags: tuple[float, ...] | list[float]) -> int:
    """The thermistor's first-order lags ``tau r_k' = r_{k-1} - r_k`` (``r_0``: row 0, the body) in
    rows ``first_row ..`` of the rate matrix; the row that holds the reading (0 without lags)."""
    prev = 0
    for j, tau in enumerate(lags):
        row = first_row + j
        matrix[row, prev] += 1.0 / tau
        matrix[row, row] -= 1.0 / tau
        prev = row
    return prev


def reference_channel(
    t: np.ndarray,
    *,
    heat_capacity: float,
    loss: float,
    conductance: float,
    k_w_mk: float,
    diffusivity_m2_s: float,
    spreading: float = 0.0,
    lag1_s: float = 0.0,
    lag2_s: float = 0.0,
    kp: float = 0.0,
    ki: float = 0.0,
    v0: float = 1.0,
    drift_k_s: float = 0.0,
    power_step: float = 0.0,
    power_step_s: float = 0.0,
    gradient_k_m: float = 0.0,
    cells: int = 300,
) -> np.ndarray:
    """Reading deviation from its value at the contact onset, at times ``t`` (s, increasing, > 0).

    ``drift_k_s``: before contact the body ramped at this rate under a net heating ``C r`` that goes
    on after it, and the lag states trail the body by their time constants (open loop only);
    ``power_step`` (W/m^2): the heater's power changes by this much at ``power_step_s`` (>= 0);
    ``gradient_k_m``: the object's temperature grows with depth at this rate before contact (a
    slab only: ``spreading = 0``), held at the far end.
    """
    if gradient_k_m and spreading > 0:
        raise ValueError("gradient_k_m needs a slab (spreading = 0)")
    t = np.asarray(t, dtype=np.float64)
    alpha = diffusivity_m2_s
    first = min(np.sqrt(alpha * t.min()) / 40, 0.1 * k_w_mk / conductance)
    length = 12 * np.sqrt(alpha * t.max())
    widths = first * ((length / first) ** (1.0 / cells)) ** np.arange(cells)
    faces = np.concatenate([[0.0], np.cumsum(widths)])
    centres = 0.5 * (faces[1:] + faces[:-1])
    if spreading > 0:
        a = k_w_mk / spreading
        area = ((a + faces) / a) ** 2
        volume = ((a + faces[1:]) ** 3 - (a + faces[:-1]) ** 3) / (3 * a**2)
        radius = a + centres
    else:
        area = np.ones_like(faces)
        volume = widths.copy()
        radius = centres
    rho_c = k_w_mk / alpha
    # states: 0 sensor u, 1..cells object cells, then lag states, then the controller's integral
    lags = [tau for tau in (lag1_s, lag2_s) if tau > 0]
    n = 1 + cells + len(lags) + (1 if ki > 0 else 0)
    a_mat = np.zeros((n, n))
    b = np.zeros(n)
    g0 = 1.0 / (1.0 / conductance + widths[0] / (2 * k_w_mk))
    links = k_w_mk * area[1:cells] / np.diff(radius)
    # sensor: C u' = dQ - G u - g0 (V0 + u - theta_1)
    a_mat[0, 0] = -(loss + g0) / heat_capacity
    a_mat[0, 1] = g0 / heat_capacity
    b[0] = -g0 * v0 / heat_capacity
    # object cells (far end held at the object's temperature)
    cap = rho_c * volume
    a_mat[1, 0] += g0 / cap[0]
    a_mat[1, 1] -= g0 / cap[0]
    b[1] += g0 * v0 / cap[0]
    add_conduction_chain(a_mat, 1, links, cap)
    a_mat[cells, cells] -= k_w_mk * area[cells] / (faces[cells] - centres[-1]) / cap[-1]
    # lag chain: tau r_k' = r_{k-1} - r_k, r_0 = u
    reading = add_lag_chain(a_mat, 1 + cells, lags)
    # controller dQ = -kp r - ki I, I' = r
    a_mat[0, reading] -= kp / heat_capacity
    if ki > 0:
        row = n - 1
        a_mat[0, row] -= ki / heat_capacity
        a_mat[row, reading] += 1.0
    # the ramp before contact: a net heating C r goes on; lag state k trails the body by the sum of
    # the time constants up to it (a first-order chain in a steady ramp)
    y0 = np.zeros(n)
    if gradient_k_m:  # the object's cells start on the line, the far end held on it
        y0[1 : 1 + cells] = gradient_k_m * centres
        b[cells] += k_w_mk * area[cells] / (faces[cells] - centres[-1]) / cap[-1] * gradient_k_m * faces[cells]
    b[0] += drift_k_s  # S / C = r
    trail = 0.0
    for j, tau in enumerate(lags):
        trail += tau
        y0[1 + cells + j] = -drift_k_s * trail
    # a stiff implicit integrator (Radau, tight tolerances, the constant Jacobian given): no
    # eigen-decomposition, so equal lags (a Jordan block) need no special case
    jac = sparse.csr_matrix(a_mat)  # tridiagonal plus a few entries: sparse LU in every step
    scale = max(abs(v0), abs(drift_k_s), abs(power_step) / heat_capacity, 1.0)
    step_at = power_step_s if power_step else float(t.max())
    pieces = [(0.0, min(step_at, float(t.max())), b)]
    if power_step and step_at < t.max():
        b_after = b.copy()
        b_after[0] += power_step / heat_capacity
        pieces.append((step_at, float(t.max()), b_after))
    out = np.empty(len(t))
    y = y0
    for start, stop, rhs in pieces:
        inside = (t >= start) & (t <= stop)
        if stop <= start:
            continue
        sol = integrate.solve_ivp(
            lambda _t, y_, rhs=rhs: jac @ y_ + rhs,
            (start, stop),
            y,
            method="Radau",
            t_eval=np.concatenate([t[inside], [stop]]) if not inside.any() or t[inside][-1] < stop else t[inside],
            rtol=1e-9,
            atol=1e-12 * scale,
            jac=jac,
        )
        if not sol.success:  # pragma: no cover - a failure of the reference itself
            raise RuntimeError(sol.message)
        out[inside] = sol.y[reading][: inside.sum()]
        y = sol.y[:, -1]
    return np.asarray(out) + drift_k_s * sum(lags)  # relative to the reading at the onset


def varying_contact_reading(
    t: np.ndarray,
    h_of_t: object,
    *,
    heat_capacity: float,
    loss: float,
    k_w_mk: float,
    diffusivity_m2_s: float,
    lags: tuple[float, ...],
    start_s: float,
    cells: int = 260,
    power_of_t: object = None,
    v0: float = 1.0,
) -> np.ndarray:
    """Reading deviation (``v0``: the body's start above the object) at times ``t`` for an interface
    conductance ``h_of_t(time)`` (0 before the contact; the approach's gap, a contact whose
    conductance steps) from ``start_s`` on; a slab object on a graded grid. ``power_of_t(time)``
    (W/m^2): a heater power into the body (none by default)."""
    span = float(t.max()) - start_s
    first = np.sqrt(diffusivity_m2_s * 1e-3) / 10
    length = 12 * np.sqrt(diffusivity_m2_s * span)
    widths = first * ((length / first) ** (1.0 / cells)) ** np.arange(cells)
    faces = np.concatenate([[0.0], np.cumsum(widths)])
    centres = 0.5 * (faces[1:] + faces[:-1])
    cap = k_w_mk / diffusivity_m2_s * widths
    n = 1 + cells + len(lags)
    base = np.zeros((n, n))
    links = k_w_mk / np.diff(centres)
    add_conduction_chain(base, 1, links, cap)
    base[cells, cells] -= k_w_mk / (faces[-1] - centres[-1]) / cap[-1]
    base[0, 0] = -loss / heat_capacity
    prev = add_lag_chain(base, 1 + cells, lags)
    # the interface: flux g (1 + u - theta_1) out of the body into the first cell, g the gap's
    # conductance in series with half the first cell
    couple = np.zeros((n, n))
    couple[0, 0], couple[0, 1] = -1.0 / heat_capacity, 1.0 / heat_capacity
    couple[1, 0], couple[1, 1] = 1.0 / cap[0], -1.0 / cap[0]
    drive = np.zeros(n)
    drive[0], drive[1] = -v0 / heat_capacity, v0 / cap[0]
    base_s, couple_s = sparse.csr_matrix(base), sparse.csr_matrix(couple)

    def g(time: float) -> float:
        h = float(h_of_t(time))  # type: ignore[operator]
        return 0.0 if h <= 0 else 1.0 / (1.0 / h + widths[0] / (2 * k_w_mk))

    heat = np.zeros(n)
    heat[0] = 1.0 / heat_capacity

    def power(time: float) -> float:
        return 0.0 if power_of_t is None else float(power_of_t(time))  # type: ignore[operator]

    sol = integrate.solve_ivp(
        lambda time, y: base_s @ y + g(time) * (couple_s @ y + drive) + power(time) * heat,
        (start_s, float(t.max())),
        np.zeros(n),
        method="Radau",
        t_eval=t,
        rtol=1e-8,
        atol=1e-11,
        jac=lambda time, y: base_s + g(time) * couple_s,
        max_step=0.01,
    )
    assert sol.success, sol.message
    return np.asarray(sol.y[prev])


def numerical_excess(
    t: np.ndarray,
    heat_capacity: float,
    loss: float,
    conductance: float,
    k_w_mk: float,
    diffusivity_m2_s: float,
    spreading: float = 0.0,
    v0: float = 1.0,
    heating: float = 0.0,
    cells: int = 400,
) -> np.ndarray:
    """Independent numerical solution of the same problem (a check of the analytic formula).

    Finite volumes in space on a geometrically graded grid; exact in time (eigen-decomposition of
    the symmetrised linear system, so no time-stepping error). ``spreading = 0`` solves the seed's
    1-D slab ``u_t = alpha u_xx``; ``spreading > 0`` solves a spherical cavity of radius
    ``a = k / spreading`` in an infinite body (``u_t = alpha (u_rr + 2 u_r / r)``), whose surface
    admittance is exactly ``e sqrt(s) + k / a``. The sensor node obeys
    ``C v' = S + G V0 - G v - H (v - u_surface)``. Returns ``v`` at the times ``t`` (s, > 0).
    """
    t = np.asarray(t, dtype=np.float64)
    alpha = diffusivity_m2_s
    t_min, t_max = float(t.min()), float(t.max())
    # grid: first cell resolves the shortest diffusion length, the body reaches 12 of the longest
    first = min(np.sqrt(alpha * t_min) / 40, 0.1 * k_w_mk / max(conductance, 1e-300) + 1e-12)
    length = 12 * np.sqrt(alpha * t_max)
    ratio = (length / first) ** (1.0 / cells)  # geometric widths summing to about ``length``
    widths = first * ratio ** np.arange(cells)
    faces = np.concatenate([[0.0], np.cumsum(widths)])
    centres = 0.5 * (faces[1:] + faces[:-1])
    if spreading > 0:
        a = k_w_mk / spreading
        r_faces, r_centres = a + faces, a + centres
        area = (r_faces / a) ** 2  # face area per unit contact area
        volume = (r_faces[1:] ** 3 - r_faces[:-1] ** 3) / (3 * a**2)
    else:
        area = np.ones_like(faces)
        volume = widths.copy()
        r_centres = centres
    rho_c = k_w_mk / alpha
    cap = np.concatenate([[heat_capacity], rho_c * volume])
    # conductances of the chain: sensor -> first cell centre (the interface conductance in series
    # with half a cell of body), then cell centre to cell centre; the far end is held at 0
    g0 = 1.0 / (1.0 / conductance + widths[0] / (2 * k_w_mk))
    links = np.concatenate([[g0], k_w_mk * area[1:cells] / np.diff(r_centres)])
    diag = np.zeros(cells + 1)
    diag[:-1] -= links
    diag[1:] -= links
    diag[0] -= loss
    # C y' = K y + b with b = (S + G V0) e_0, y(0) = V0 e_0. K is tridiagonal and symmetric: with
    # y = M^-1/2 z it becomes z' = A z + M^-1/2 b, A = M^-1/2 K M^-1/2 symmetric tridiagonal
    m = 1.0 / np.sqrt(cap)
    lam, vec = linalg.eigh_tridiagonal(diag * m * m, links * m[:-1] * m[1:])
    first = vec[0]  # only the sensor node is needed: y0 and b live on node 0
    z0 = first * v0 / m[0]
    bz = first * (heating + loss * v0) * m[0]
    lt = lam[None, :] * t[:, None]
    # per mode: z(t) = z0 e^(lam t) + bz (e^(lam t) - 1) / lam; lam < 0 (the held far end makes K
    # negative definite), expm1 keeps small lam t accurate
    growth = np.expm1(lt) / np.where(lam == 0, 1.0, lam)[None, :]
    z = z0[None, :] * np.exp(lt) + bz[None, :] * growth
    return (z * first[None, :]).sum(axis=1) * m[0]


def channel_of_material(material: str, params: dict[str, float]) -> tuple[ChannelModel, float, float]:
    """A one-touch channel model on ``material`` (its effusivity) with ``params``, and the
    material's conductivity (W/(m K)) and diffusivity (m^2/s) for the reference solver."""
    m = get_material(material)
    return ChannelModel.create(effusivity=m.effusivity, **params), m.k_w_mk, m.diffusivity_mm2_s * 1e-6


def relative_max_error(closed: np.ndarray, ref: np.ndarray) -> float:
    """Largest deviation of a closed form from the reference, relative to the reference's peak."""
    return float(np.max(np.abs(closed - ref)) / np.max(np.abs(ref)))
