"""The frame stream's input check and idle gate for a batch of one small frame, on Python floats.

:class:`~tactile_learn.frame_stream.FrameStream` checks every batch with two numpy reductions and
gates it with a vectorised pass (:meth:`~tactile_learn.idle.IdleGate.active`): some ten numpy
calls, ~8 us for one frame of six FSR readings, which is most of what a skipped idle frame costs
(and with 80 % idle frames, half of a gated stream's time). For one frame of a few values the same
decisions on Python floats take ~1-2 us. They are the same decisions: the range check compares the
values with the same bounds (as the full check does, in double precision), and the gate's largest
deviation, computed in double precision from the gate's float32 mean and scale, differs from the
gate's float32 arithmetic by a few float32 roundings at most: a frame within a relative 1e-6 of
the threshold is left to :meth:`IdleGate.active` itself.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from tactile_learn.idle import IdleGate

__all__ = ["OneFrameGate"]

#: frames with more values than this keep the numpy path (their loop in Python would cost more)
MAX_VALUES = 16
#: relative band around the gate's threshold left to the float32 gate (its roundings are ~1e-7)
_BAND = 1e-6


class OneFrameGate:
    """Range check and idle gate of one frame (module docstring); built once per stream."""

    def __init__(self, shape: tuple[int, ...], bounds: tuple[float, float, bool], gate: IdleGate | None) -> None:
        self.batch_shape = (1, *shape)
        self.low, self.high, self.strict = bounds
        self.gate = gate
        if gate is not None:
            self.pairs = list(zip(gate.mean.tolist(), gate.inv_sd.tolist(), strict=True))
            self.above = float(gate.threshold) * (1.0 + _BAND)
            self.below = float(gate.threshold) * (1.0 - _BAND)

    @classmethod
    def build(
        cls, shape: tuple[int, ...], bounds: tuple[float, float, bool] | None, gate: IdleGate | None
    ) -> OneFrameGate | None:
        """The one-frame path of a stream, or ``None`` where it does not apply (a sensor whose check
        maps its readings, or frames of many values)."""
        if bounds is None or int(np.prod(shape)) > MAX_VALUES:
            return None
        return cls(shape, bounds, gate)

    def plain_verdict(self, frames: Any) -> bool | None:
        """:meth:`verdict` of ``frames`` where they are a float32 C-contiguous batch of one frame
        of the stream's shape; ``None`` for anything else (the full check's case)."""
        if (
            type(frames) is np.ndarray
            and frames.shape == self.batch_shape
            and frames.dtype == np.float32
            and frames.flags.c_contiguous
        ):
            return self.verdict(frames)
        return None

    def verdict(self, frames: np.ndarray) -> bool | None:
        """For ``frames``, a float32 C-contiguous batch of one frame: ``True`` (valid and active, or
        no gate), ``False`` (valid and idle), or ``None``: not a plain valid frame (out of range,
        NaN or inf): the stream's full check answers with its clear error."""
        values = frames.ravel().tolist()
        low, high = self.low, self.high
        # NaN fails every comparison
        ok = all(low < v < high for v in values) if self.strict else all(low <= v < high for v in values)
        if not ok:
            return None
        if self.gate is None:
            return True
        deviation = max([abs(v - m) * s for v, (m, s) in zip(values, self.pairs, strict=True)], default=0.0)
        if deviation > self.above:
            return True
        if deviation < self.below:
            return False
        return bool(self.gate.active(frames)[0])  # within rounding of the threshold: the gate decides
