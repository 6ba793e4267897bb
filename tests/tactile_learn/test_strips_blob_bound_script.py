"""scripts/strips_blob_bound.py: the smooth field's bound above the intersection rule."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_blob_bound as bound


def test_the_generative_model_reproduces_the_simulator_from_the_latents() -> None:
    frames = bound.test_frames(24, 3)
    model = bound.BlobModel(bound.family_scene())
    u = np.stack([model.uniforms_of(frames, i) for i in range(24)])
    loads, maps = model(u)
    ideal = model.sensor.invert_readings(frames["readings_ideal"].astype(np.float64))
    # the fits' residuals are in noise units: the model must sit far inside one
    assert np.abs(loads - ideal).max() < 0.05 * model.sensor.load_noise().min()
    np.testing.assert_allclose(maps, frames["pressure"], rtol=1e-3, atol=1e-3 * float(frames["pressure"].max()))


def test_the_three_readings_share_their_shapes_and_differ_by_the_noise() -> None:
    frames = bound.test_frames(16, 5)
    assert not np.array_equal(frames["readings"], frames["readings_clean"])
    assert not np.array_equal(frames["readings_clean"], frames["readings_ideal"])  # the gain spread
    assert np.abs(frames["readings"] - frames["readings_clean"]).max() < 0.05  # volts: noise, not a new shape


def test_paired_difference_and_its_standard_error() -> None:
    a, b = np.array([1.0, 2.0, np.nan, 4.0]), np.array([0.5, 1.0, 1.0, 3.0])
    out = bound.paired(a, b)
    assert out["mean"] == pytest.approx(np.mean([0.5, 1.0, 1.0]))
    assert out["se"] == pytest.approx(np.std([0.5, 1.0, 1.0]) / np.sqrt(3))


@pytest.mark.parametrize(("readings", "fits"), [("noisy", "1"), ("ideal", "0")])
def test_end_to_end_small(tmp_path: Path, readings: str, fits: str) -> None:
    pytest.importorskip("torch", reason="torch (training extra) is not installed")
    out = tmp_path / "bound.json"
    argv = ["--n-test", "40", "--models", "--n-train", "600", "--n-val", "100", "--hidden", "16", "--epochs", "1"]
    argv += ["--specialist-readings", readings, "--fit-frames", fits, "--fit-starts", "2", "--n-library", "200"]
    assert bound.main([*argv, "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    rule = result["noise"]["intersection"]
    assert 0.5 < rule["noisy"] <= 1.0 and set(rule) == {"noisy", "no_electrical_noise", "no_noise_no_gain_spread"}
    specialist = result["specialist"]
    assert len(specialist["val_r_by_epoch"]) == 2
    assert specialist["readings"] == {"noisy": "noisy", "ideal": "no_noise_no_gain_spread"}[readings]
    assert ("ambiguity" in result) == (fits != "0")


def test_seeds_must_differ() -> None:
    with pytest.raises(SystemExit):
        bound.main(["--test-seed", "5", "--train-seed", "5"])
