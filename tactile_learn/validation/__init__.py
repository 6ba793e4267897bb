"""Input checks, one module per sensor, below the estimators and the tasks (both call them).

- :mod:`~tactile_learn.validation.common`: a batch of numbers of the right shape, finite, not
  negative, below a saturation value (:func:`as_batch`);
- :mod:`~tactile_learn.validation.strips`, :mod:`~tactile_learn.validation.fsr`,
  :mod:`~tactile_learn.validation.thermal`, :mod:`~tactile_learn.validation.capacitive`: each
  sensor's readings against its scene's readout (shape, the ADC's range, a calibrated film's mapping).

Every check raises :class:`~synth.errors.InputError` naming the array and the problem.
"""

from tactile_learn.validation.capacitive import capacitive_input
from tactile_learn.validation.common import as_batch
from tactile_learn.validation.fsr import fsr_bounds, fsr_input
from tactile_learn.validation.strips import strips_bounds, strips_input
from tactile_learn.validation.thermal import thermal_bounds, thermal_input, thermal_input_shape

__all__ = [
    "as_batch",
    "capacitive_input",
    "fsr_bounds",
    "fsr_input",
    "strips_bounds",
    "strips_input",
    "thermal_bounds",
    "thermal_input",
    "thermal_input_shape",
]
