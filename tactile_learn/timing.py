"""The one latency timer: every benchmark, script and report times ``predict`` with it.

Latency is measured per frame at batch 1 after warm-up calls (median and 99th percentile, in
microseconds), and throughput at batch 1024 (frames per second, median of repeats). Medians, not
means: a busy machine adds a long tail that says nothing about the method.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["time_predict"]


def time_predict(
    predict: Callable[[np.ndarray], Any],
    inputs: np.ndarray,
    *,
    repeats: int,
    budget_s: float,
    warmup: int = 5,
) -> dict[str, float]:
    """Latency per frame at batch 1 (p50, p99 in us) and throughput at batch 1024 (frames/s)."""
    n = len(inputs)
    for i in range(warmup):
        predict(inputs[i % n : i % n + 1])
    times: list[float] = []
    deadline = time.perf_counter() + budget_s
    i = 0
    while i < repeats and (i < 10 or time.perf_counter() < deadline):
        frame = inputs[i % n : i % n + 1]
        start = time.perf_counter()
        predict(frame)
        times.append(time.perf_counter() - start)
        i += 1
    big = np.resize(inputs, (1024, *inputs.shape[1:])).astype(np.float32)
    predict(big)
    batch_times: list[float] = []
    deadline = time.perf_counter() + budget_s
    for k in range(max(3, repeats // 50)):
        start = time.perf_counter()
        predict(big)
        batch_times.append(time.perf_counter() - start)
        if k >= 2 and time.perf_counter() > deadline:
            break
    us = np.array(times) * 1e6
    return {
        "latency_us_p50_b1": float(np.median(us)),
        "latency_us_p99_b1": float(np.percentile(us, 99)),
        "throughput_fps_b1024": float(1024 / np.median(batch_times)),
        "latency_samples": len(times),
    }
