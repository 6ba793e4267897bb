"""One exception family for the whole project.

It lives in ``synth`` (the bottom layer) so that the simulator can raise it without importing
``tactile_learn``; ``tactile_learn`` re-exports it. The CLI turns any ``TactileError`` into a
one-line message and a non-zero exit code.
"""

from __future__ import annotations


class TactileError(Exception):
    """Base class of every error this project raises on purpose."""


class ConfigError(TactileError, ValueError):
    """A scene or configuration value is unknown, of the wrong type, or out of range."""


class InputError(TactileError, ValueError):
    """Array input has the wrong shape or dtype, or holds NaN/inf, negative or saturated values."""


class ModelError(TactileError):
    """A model file or model card is missing, corrupt, or does not match what it is used for."""


class DataError(TactileError):
    """A dataset or recording is missing, corrupt, truncated, or not what was asked for."""
