"""tactile-learn: simulate soft tactile and thermal sensors and invert their readings.

``import tactile_learn`` stays light: numpy and scipy only. Torch is imported only by training
and export; the ONNX runtime only by :mod:`tactile_learn.runtime`.
"""

from __future__ import annotations

from synth import __version__
from synth.errors import ConfigError, DataError, InputError, ModelError, TactileError
from tactile_learn import _moved

_moved.install()  # old import paths of moved modules (tactile_learn/_moved.py)

__all__ = ["ConfigError", "DataError", "InputError", "ModelError", "TactileError", "__version__"]
