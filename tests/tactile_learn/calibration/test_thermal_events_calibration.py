"""A whole calibration with contact events (nuisance "contact_events") on simulated touches of the
robot sensor: the events are placed, refined within their bounds and reported, and the rest of the
report keeps its shape. The touches have no steps, yet the fit here stays in a local minimum (~12
sigma, see test_thermal_touch_contact.py) whose bends pass the kink gate: events are placed there
too, which is why the term stays opt-in (docs/thermal-real.md, contact events)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from synth.materials import get_material
from tactile_learn.calibration.thermal_calibration import calibrate_channels
from tactile_learn.calibration.thermal_parameters import EVENT_FACTOR_MAX, EVENT_SHIFT_S
from tactile_learn.calibration.thermal_touches import prepare_touches
from tests.tactile_learn.test_thermal_real import robot_scene, simulated_series

pytestmark = pytest.mark.slow  # a 4-touch calibration: ~25 s of CPU


def test_a_calibration_with_contact_events_reports_them() -> None:
    scene = robot_scene(**{"contact.conductance_w_m2k": [450.0, 2200.0], "objects.offset_k": [-12.0, -6.0]})
    series, noise, _ = simulated_series(scene, 4, 5)
    classes = [[get_material("aluminium")], [get_material("oak")]]
    result = calibrate_channels(prepare_touches(series), classes, noise, starts=2, nuisance=("contact_events",))
    report = result.report
    events = report["contact_events"]
    assert events["count"] == len(events["events"]) > 0 and events["factor_bounds"] == [0.5, 2.0]
    for row in events["events"]:
        assert row["touch"] in {f"t{i}" for i in range(4)}
        # after the press's transient (kinks after 0.8 s, an event up to 0.6 + 0.15 s before its kink)
        assert row["t_s"] >= 0.8 - 0.6 - EVENT_SHIFT_S[1] - 1e-9
        for ch in ("heated", "passive"):
            assert 1 / EVENT_FACTOR_MAX - 1e-9 <= row[f"{ch}_factor"] <= EVENT_FACTOR_MAX + 1e-9
            assert np.isfinite(row[f"{ch}_sd_log"])
            at_bound = abs(math.log(row[f"{ch}_factor"])) > math.log(EVENT_FACTOR_MAX) * (1 - 2e-3)
            assert row.get(f"{ch}_at_bound", False) == at_bound
    assert (events["why_at_bound"] is not None) == (events["factors_at_bound"] > 0)
    # the touches' own contacts are reported as before (the events' parameters apart)
    assert set(report["touch_contact"]) == {
        "touch.log_conductance_factor",
        "touch.lead_offset_s",
        "touch.log_ramp_factor",
    }
    residual = report["residual"]
    assert residual["rms_k"] < 0.5 * residual["shared_contact"]["rms_k"]
    assert sum(w["samples"] for w in residual["windows"]["heated"]) > 0
    assert "contact events" in report["model"]
