"""One frame through an ONNX model at the cost of the graph: the batch-1 path of ``predict``.

At batch 1 the network's arithmetic is small and the fixed costs around it are not: the full
input check (a dozen numpy calls, ~3 us), ``session.run``'s feed dict, output list and fresh
output arrays (~5 us on the FSR model), and the result's finishing. :class:`OneFrameRun` does the
same work with its set-up done once (in ``OnnxEstimator.prepare``, or once per stream):

- the frame is copied into an input buffer bound to the session (an io binding: onnxruntime reads
  it and writes the first output into a bound output buffer; no dict, no allocation per call);
- the copy is checked with one reduction: the sensors' valid range is ``0 <= x < high``, and
  non-negative float32 values order like their bit patterns read as unsigned integers, while
  every negative value, -0.0, NaN and inf reads as a larger integer than any value below ``high``
  (sign bit set, or an exponent of all ones): ``max(bits) < bits(high)`` is the whole range check.
  A frame it refuses (bad input, or -0.0 which the full check accepts) takes the full path, which
  gives the clear error (or the answer);
- the task finishes the result from the buffers (the FSR task's one-press check on Python floats,
  :meth:`~tactile_learn.tasks.fsr.FsrTask.one_frame_finisher`), into a new array the caller keeps.

The buffers belong to one caller at a time: a second thread arriving while a frame is in flight
finds the lock taken and goes the ordinary way (``session.run`` is thread-safe), so ``predict``
stays safe to share. The results are those of the fully checked path bit for bit (the same graph
on the same values; tests).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["OneFrameRun", "below_bits"]

#: ``finish(frame, result)``: the prediction from the bound input ``frame`` (1, *shape) and the
#: graph's first output ``result`` (1, *out_shape), as a new array (both buffers are reused)
FrameFinisher = Callable[[np.ndarray, np.ndarray], np.ndarray]

_max_of = np.maximum.reduce
_min_of = np.minimum.reduce
_FLOAT32 = np.dtype(np.float32)
#: frames of up to this many values are range-checked in Python (fewer calls than numpy's)
_FEW_VALUES = 16


def below_bits(high: float) -> int:
    """The unsigned bit pattern one past that of the largest float32 value ``v`` with ``v < high``
    (``high`` a finite positive double): for float32 ``x >= 0``, ``x < high`` exactly when
    ``bits(x) < below_bits(high)``."""
    top = np.float32(high)  # the nearest float32: may lie at or above high
    if float(top) >= high:
        top = np.nextafter(top, np.float32(0.0))
    return int(np.array(top, dtype=np.float32).view(np.uint32)) + 1


class OneFrameRun:
    """Check, run and finish one frame (module docstring); ``None`` from :meth:`__call__` means
    "not a plain valid frame, or busy: take the ordinary path"."""

    def __init__(
        self,
        session: Any,
        input_name: str,
        output_name: str,
        frame_shape: tuple[int, ...],
        output_shape: tuple[int, ...],
        bounds: tuple[float, float, bool],
        finish: FrameFinisher,
    ) -> None:
        import onnxruntime as ort

        self.batch_shape = (1, *frame_shape)
        self.frame = np.zeros(self.batch_shape, dtype=np.float32)
        self.result = np.zeros((1, *output_shape), dtype=np.float32)
        binding = session.io_binding()
        binding.bind_ortvalue_input(input_name, ort.OrtValue.ortvalue_from_numpy(self.frame))
        binding.bind_ortvalue_output(output_name, ort.OrtValue.ortvalue_from_numpy(self.result))
        self._binding = binding
        self._run_bound = session.run_with_iobinding
        self._finish = finish
        self._lock = threading.Lock()
        self._low, self._high, self._strict = bounds
        self._valid = self._bits_check() or self._range_check

    def _bits_check(self) -> Callable[[], bool] | None:
        """The one-reduction check (module docstring) where the range is ``0 <= x < high``: the
        buffer's bit patterns as unsigned integers, their maximum by Python's ``max`` over a
        memoryview for a few values (~0.2 us for six) and by numpy beyond (~0.9 us whatever the size)."""
        if self._low != 0.0 or self._strict or not (math.isfinite(self._high) and self._high > 0.0):
            return None
        limit = below_bits(self._high)
        if self.frame.size <= _FEW_VALUES:
            words = self.frame.data.cast("B").cast("I")  # uint32, the platform's byte order
            return lambda: max(words) < limit
        bits = self.frame.reshape(-1).view(np.uint32)
        return lambda: bool(_max_of(bits) < limit)

    def _range_check(self) -> bool:
        """Another range (a lower bound, negative values allowed): two reductions, NaN propagating
        into both."""
        frame = self.frame
        low, high = float(_min_of(frame, None)), float(_max_of(frame, None))
        return (low > self._low if self._strict else low >= self._low) and high < self._high

    def __call__(self, x: Any) -> np.ndarray | None:
        """The prediction for ``x``, a float32 batch of one frame, or ``None`` (see the class)."""
        # (the builtin float32 dtype is one object: another byte order takes the ordinary path)
        if type(x) is not np.ndarray or x.dtype is not _FLOAT32 or x.shape != self.batch_shape:
            return None
        if not self._lock.acquire(blocking=False):
            return None
        try:
            self.frame[...] = x
            if not self._valid():
                return None
            self._run_bound(self._binding)
            return self._finish(self.frame, self.result)
        finally:
            self._lock.release()

    def run_checked(self, x: np.ndarray) -> np.ndarray:
        """The prediction for ``x``, one frame the caller has checked (a stream's own check);
        for one caller at a time (a stream builds its own run)."""
        self.frame[...] = x
        self._run_bound(self._binding)
        return self._finish(self.frame, self.result)
