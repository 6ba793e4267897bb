"""Calibration with every touch's own contact: simulated touches of the robot sensor whose contact
conductance differs from touch to touch (a press is never the same twice). One shared contact
cannot explain them; the joint refinement with each touch's own contact explains them much better."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from synth.materials import get_material
from tactile_learn.calibration.thermal_calibration import calibrate_channels
from tactile_learn.calibration.thermal_touches import prepare_touches
from tests.tactile_learn.test_thermal_real import robot_scene, simulated_series

pytestmark = pytest.mark.slow  # a 4-touch calibration: ~25 s of CPU


@pytest.fixture(scope="module")
def fitted() -> tuple[dict[str, Any], np.ndarray]:
    scene = robot_scene(**{"contact.conductance_w_m2k": [450.0, 2200.0], "objects.offset_k": [-12.0, -6.0]})
    series, noise, arrays = simulated_series(scene, 4, 5)
    names = scene.sensor.class_names  # type: ignore[attr-defined]
    classes = [[get_material("aluminium")], [get_material("oak")]]
    assert list(names) == ["metal", "wood"]
    result = calibrate_channels(prepare_touches(series), classes, noise, starts=2)
    return result.report, arrays["latent_conductance_w_m2k"][:, 0]


def test_each_touch_with_its_own_contact_explains_more(fitted: tuple[dict[str, Any], np.ndarray]) -> None:
    """The joint refinement must at least explain the touches much better than one shared contact
    (on these 4 touches from 2 starts the shared stage lands in a local minimum and the own-contact
    residual stays above 3 sigma: the optimiser, not the model, is what limits it here)."""
    report, truth = fitted
    residual = report["residual"]
    assert residual["rms_k"] < 0.7 * residual["shared_contact"]["rms_k"], residual
    for channel in ("heated", "passive"):
        assert residual[channel]["rms_k"] < residual["shared_contact"][channel]["rms_k"], residual
    assert residual["rms_sigma_precontact"] > 0 and set(report["touch_contact"]) == {
        "touch.log_conductance_factor",
        "touch.lead_offset_s",
        "touch.log_ramp_factor",
    }
    # the touches' factors are reported, with their spread
    factors = np.array([row["touch_conductance_factor"] for row in report["per_touch"]])
    assert len(factors) == len(truth) and np.all(factors > 0) and factors.max() / factors.min() > 1.5
