"""synth: physics simulators of soft tactile and thermal sensors (numpy/scipy only).

This layer knows nothing of learning: it never imports torch or ``tactile_learn``.
"""

from __future__ import annotations

__version__ = "0.1.0"

from synth.errors import ConfigError, DataError, InputError, ModelError, TactileError

__all__ = ["ConfigError", "DataError", "InputError", "ModelError", "TactileError", "__version__"]
