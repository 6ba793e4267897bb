"""Moved to :mod:`tactile_learn.calibration.thermal_calibration`; this name is kept for old imports."""

import sys

from tactile_learn.calibration import thermal_calibration

sys.modules[__name__] = thermal_calibration
