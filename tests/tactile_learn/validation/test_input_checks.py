"""Each sensor's input check: its fast-path bounds agree with the full check, bad input is named."""

from __future__ import annotations

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.errors import InputError
from synth.scene import load_scene
from tactile_learn.tasks import TASK_NAMES, get_task
from tactile_learn.validation import InputCheck, fsr_input, strips_input, thermal_input


@pytest.mark.parametrize("task_name", TASK_NAMES)
def test_bounds_agree_with_the_check(task_name: str) -> None:
    task = get_task(task_name)
    scene = load_scene(task.default_scene)
    check = task.input_check(scene)
    x = np.ascontiguousarray(task.example_inputs(simulate_shard(scene, 11, 0, 2), scene)[:4], dtype=np.float32)
    assert check(x) is x or np.array_equal(check(x), x)  # valid float32 input passes unchanged
    bounds = task.fast_bounds(scene)
    if bounds is None:
        return
    low, high, strict = bounds
    assert (x.min() > low if strict else x.min() >= low) and x.max() < high
    if np.isfinite(high):
        above = x.copy()
        above.flat[0] = high
        with pytest.raises(InputError, match="saturated"):
            check(above)
    if np.isfinite(low):
        below = x.copy()
        below.flat[0] = low - (0.0 if strict else 1.0)
        with pytest.raises(InputError):
            check(below)


def test_the_per_sensor_functions_are_the_tasks_checks() -> None:
    strips, fsr, thermal = (load_scene(n) for n in ("strips16", "fsr6", "thermal"))
    with pytest.raises(InputError, match="expected shape"):
        strips_input(np.zeros((1, 31), np.float32), strips.sensor)
    with pytest.raises(InputError, match="ADC's full scale"):
        fsr_input(np.full((1, 6), 1e9, np.float32), fsr.sensor)
    lo = thermal.sensor.readout.adc_range_c[0]
    window = np.full((1, thermal.sensor.window_samples), lo, np.float32)
    with pytest.raises(InputError, match="ADC's bottom"):
        thermal_input(window, thermal.sensor)


def test_an_input_check_maps_only_after_checking() -> None:
    check = InputCheck((2,), upper=10.0, extra=lambda b: b * 2)
    np.testing.assert_array_equal(check(np.array([[1.0, 2.0]])), [[2.0, 4.0]])
    assert check.bounds() is None  # a mapping check has no fast path
    assert check(np.zeros((0, 2))).shape == (0, 2)
    with pytest.raises(InputError, match="NaN"):
        check(np.array([[np.nan, 1.0]]))
