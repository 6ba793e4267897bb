"""synth.sensors.thermal.readout.drift_ending_at_contact: a reading-side drift the contact ends."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from synth.sensors.thermal.readout import drift_ending_at_contact


def test_drift_end_matches_the_lag_ode() -> None:
    # tau d'' + d' = 0 from d(0) = 0, d'(0) = 1 (the slope relaxes through a first-order lag)
    tau = 0.3
    t = np.linspace(0.0, 2.0, 201)
    sol = solve_ivp(lambda _, y: [y[1], -y[1] / tau], (0.0, 2.0), [0.0, 1.0], t_eval=t, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(drift_ending_at_contact(t, tau), sol.y[0], rtol=1e-6, atol=1e-9)


def test_drift_end_is_the_ramp_before_the_contact_and_continuous() -> None:
    t = np.array([-1.0, -0.5, -1e-9, 0.0, 1e-9, 10.0])
    d = drift_ending_at_contact(t, 0.2)
    np.testing.assert_allclose(d[:3], t[:3])
    assert abs(d[3]) < 1e-12 and abs(d[4] - 1e-9) < 1e-12  # value and slope continuous at 0
    assert abs(d[5] - 0.2) < 1e-12  # the reading settles tau * slope above its contact value


def test_drift_end_per_row_lags_and_tiny_lag() -> None:
    t = np.linspace(-0.5, 3.0, 36)[None, :].repeat(2, axis=0)
    tau = np.array([[0.1], [1.0]])
    d = drift_ending_at_contact(t, tau)
    assert d.shape == t.shape and np.all(np.isfinite(d))
    assert d[0, -1] < d[1, -1]  # a longer lag lets the drift run on longer
    assert np.all(np.isfinite(drift_ending_at_contact(t, 0.0)))  # a zero lag: a kink, no NaN
