"""Input checks, one module per sensor, below the estimators and the tasks (both call them).

- :mod:`~tactile_learn.validation.common`: a batch of numbers of the right shape, finite, not
  negative, below a saturation value (:func:`as_batch`), and :class:`InputCheck`, the same with a
  sensor's limits worked out once (an estimator builds it in ``prepare``, not on every call);
- :mod:`~tactile_learn.validation.strips`, :mod:`~tactile_learn.validation.fsr`,
  :mod:`~tactile_learn.validation.thermal`, :mod:`~tactile_learn.validation.capacitive`: each
  sensor's readings against its scene's readout (shape, the ADC's range, a calibrated film's mapping).

Every check raises :class:`~synth.errors.InputError` naming the array and the problem.
"""

from tactile_learn.validation.capacitive import capacitive_input
from tactile_learn.validation.common import InputCheck, as_batch
from tactile_learn.validation.fsr import fsr_bounds, fsr_check, fsr_input
from tactile_learn.validation.strips import strips_bounds, strips_check, strips_input
from tactile_learn.validation.thermal import thermal_bounds, thermal_check, thermal_input, thermal_input_shape

__all__ = [
    "InputCheck",
    "as_batch",
    "capacitive_input",
    "fsr_bounds",
    "fsr_check",
    "fsr_input",
    "strips_bounds",
    "strips_check",
    "strips_input",
    "thermal_bounds",
    "thermal_check",
    "thermal_input",
    "thermal_input_shape",
]
