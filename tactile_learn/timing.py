"""The one latency timer: every benchmark, script and report times its calls with it.

- :func:`time_predict`: one estimator's latency per frame at batch 1 after warm-up calls (median and
  99th percentile, in microseconds) and its throughput at batch 1024 (frames per second, median of
  repeats): ``tactile-learn bench``.
- :func:`interleaved_times`: several callables timed in turns (round ``r`` calls each one in turn), so
  that a machine that gets busier or quieter during the run affects all of them alike: the timer of
  every ratio of two methods measured in one run (scripts, the simulator benchmark).
- :func:`summary_us`: median and tail of such times in microseconds.

Medians, not means: a busy machine adds a long tail that says nothing about the method.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

import numpy as np

__all__ = ["interleaved_times", "summary_us", "time_predict", "timed"]

T = TypeVar("T")


def timed(call: Callable[[], T]) -> tuple[T, float]:
    """What ``call()`` returns, and the seconds it took (wall clock, ``perf_counter``)."""
    start = time.perf_counter()
    result = call()
    return result, time.perf_counter() - start


def _per_key(value: int | Mapping[str, int], key: str) -> int:
    return value if isinstance(value, int) else value[key]


def interleaved_times(
    calls: Mapping[str, Callable[[np.ndarray], Any]],
    inputs: np.ndarray | Mapping[str, np.ndarray],
    *,
    rounds: int | Mapping[str, int],
    per_round: int | Mapping[str, int] = 1,
    warmup: int = 20,
    budget_s: float | None = None,
    min_rounds: int = 3,
) -> dict[str, np.ndarray]:
    """Seconds per call of every callable, timed in turns.

    Round ``r`` calls each callable ``per_round`` times on successive items of its inputs (item
    ``(r * per_round + k) % n``, kept as a batch of one: ``inputs[i : i + 1]``); a callable with
    fewer ``rounds`` of its own (a slow method) sits out the later rounds. ``warmup`` untimed calls
    first (sessions, caches, lazily built state). ``budget_s``: stop after ``min_rounds`` rounds
    once that many seconds have passed. ``inputs``: one array for all, or one per callable."""
    own = {k: inputs if isinstance(inputs, np.ndarray) else inputs[k] for k in calls}
    for key, call in calls.items():
        for i in range(warmup):
            call(own[key][i % len(own[key]) : i % len(own[key]) + 1])
    times: dict[str, list[float]] = {k: [] for k in calls}
    n_rounds = max(_per_key(rounds, k) for k in calls)
    deadline = None if budget_s is None else time.perf_counter() + budget_s
    for r in range(n_rounds):
        if deadline is not None and r >= min_rounds and time.perf_counter() > deadline:
            break
        for key, call in calls.items():
            if r >= _per_key(rounds, key):
                continue
            items, repeat = own[key], _per_key(per_round, key)
            for k in range(repeat):
                i = (r * repeat + k) % len(items)
                frame = items[i : i + 1]
                start = time.perf_counter()
                call(frame)
                times[key].append(time.perf_counter() - start)
    return {k: np.asarray(v) for k, v in times.items()}


def summary_us(seconds: np.ndarray) -> dict[str, float]:
    """Median, 90th and 99th percentile of ``seconds`` in microseconds, and how many calls."""
    us = np.asarray(seconds, dtype=np.float64) * 1e6
    return {
        "median_us": float(np.median(us)),
        "p90_us": float(np.percentile(us, 90)),
        "p99_us": float(np.percentile(us, 99)),
        "calls": len(us),
    }


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
