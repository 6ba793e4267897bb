"""The terminal summary of a real-sensor calibration keeps the residual's headline and leaves the
detail (windows, kinks, the shared-contact fit) to the report file."""

from __future__ import annotations

from tactile_learn.tasks.thermal_calibrate import residual_headline


def test_residual_headline_keeps_the_figures_a_user_reads_first() -> None:
    residual = {
        "heated": {"rms_k": 0.0099, "rms_sigma": 17.4, "rms_sigma_precontact": 40.8},
        "passive": {"rms_k": 0.0098, "rms_sigma": 49.6, "rms_sigma_precontact": 57.3},
        "rms_k": 0.0098,
        "rms_sigma": 37.2,
        "rms_sigma_precontact": 49.7,
        "within_3_sigma": False,
        "shared_contact": {"heated": {"rms_k": 0.013, "rms_sigma": 22.1}},
        "kinks": {"threshold_k_s": 0.03, "touches": [{"heated": [{"t_s": 1.45}]}] * 9},
        "windows": {"heated": [{"from_s": 0.0, "to_s": 0.5, "rms_k": 0.012}] * 8},
        "contact": "each touch with its own contact",
    }
    assert residual_headline(residual) == {
        "rms_k": 0.0098,
        "rms_sigma": 37.2,
        "within_3_sigma": False,
        "heated": {"rms_k": 0.0099, "rms_sigma": 17.4},
        "passive": {"rms_k": 0.0098, "rms_sigma": 49.6},
    }
    heated_only = {k: v for k, v in residual.items() if k != "passive"}
    assert "passive" not in residual_headline(heated_only)
