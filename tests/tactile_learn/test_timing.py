"""The one timer: calls in turns, per-callable rounds and repeats, warm-up, budget; summaries."""

from __future__ import annotations

import time

import numpy as np

from tactile_learn.timing import interleaved_times, summary_us, time_predict, timed


def test_callables_are_timed_in_turns_on_successive_frames() -> None:
    log: list[tuple[str, float]] = []
    frames = np.arange(5, dtype=np.float32)[:, None]
    calls = {name: (lambda x, name=name: log.append((name, float(x[0, 0])))) for name in ("a", "b")}
    times = interleaved_times(calls, frames, rounds=3, per_round=2, warmup=1)
    assert log[:2] == [("a", 0.0), ("b", 0.0)]  # one warm-up call each
    timed_log = log[2:]
    assert [n for n, _ in timed_log] == ["a", "a", "b", "b"] * 3
    assert [v for n, v in timed_log if n == "a"] == [0, 1, 2, 3, 4, 0]  # round r, repeat k: frame (2r + k) % 5
    assert {k: len(v) for k, v in times.items()} == {"a": 6, "b": 6}
    assert all((v >= 0).all() for v in times.values())


def test_a_slow_callable_sits_out_later_rounds_and_inputs_may_differ_per_callable() -> None:
    seen: dict[str, list[int]] = {"fast": [], "slow": []}
    calls = {k: (lambda x, k=k: seen[k].append(x.shape[1])) for k in seen}
    inputs = {"fast": np.zeros((3, 2)), "slow": np.zeros((3, 7))}
    times = interleaved_times(calls, inputs, rounds={"fast": 4, "slow": 1}, per_round={"fast": 3, "slow": 1}, warmup=0)
    assert len(times["fast"]) == 12 and len(times["slow"]) == 1
    assert set(seen["fast"]) == {2} and seen["slow"] == [7]


def test_a_budget_stops_after_the_minimum_rounds() -> None:
    calls = {"sleepy": lambda _x: time.sleep(0.002)}
    times = interleaved_times(calls, np.zeros(1), rounds=1000, warmup=0, budget_s=0.0, min_rounds=4)
    assert len(times["sleepy"]) == 4


def test_summary_and_timed() -> None:
    summary = summary_us(np.array([1e-6, 2e-6, 3e-6, 4e-6, 100e-6]))
    assert summary["median_us"] == 3.0 and summary["calls"] == 5
    assert summary["p90_us"] > summary["median_us"] and summary["p99_us"] >= summary["p90_us"]
    value, seconds = timed(lambda: 42)
    assert value == 42 and seconds >= 0


def test_time_predict_reports_latency_and_throughput() -> None:
    frames = np.ones((4, 3), dtype=np.float32)
    report = time_predict(lambda x: x * 2, frames, repeats=20, budget_s=1.0, warmup=2)
    assert report["latency_samples"] == 20
    assert report["latency_us_p99_b1"] >= report["latency_us_p50_b1"] > 0
    assert report["throughput_fps_b1024"] > 0
