"""`tactile-learn demo`: its steps, in order, as subcommands (recorded, not run: each has its own tests)."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

import tactile_learn.cli as cli
from synth.errors import TactileError
from tactile_learn.cli import demo


def _record(monkeypatch: pytest.MonkeyPatch, fail: str | None = None) -> list[list[str]]:
    calls: list[list[str]] = []

    def fake_main(argv: list[str]) -> int:
        calls.append(list(argv))
        return 1 if argv[0] == fail else 0

    monkeypatch.setattr(cli, "main", fake_main)
    return calls


def test_the_demo_trains_exports_and_evaluates_its_model_before_the_benchmark(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = _record(monkeypatch)
    assert demo.run(argparse.Namespace(out=str(tmp_path / "d"), train_n=300, skip_train=False)) == 0
    commands = [c[0] for c in calls]
    assert commands[0] == "scenes" and commands[-1] == "bench"
    assert commands.index("train") < commands.index("export") < len(commands) - 1
    train = calls[commands.index("train")]
    assert train[train.index("--data") + 1].endswith("strips16-train")
    model = calls[commands.index("export")][3]
    assert any(c[0] == "eval" and model in c for c in calls)  # the exported model is evaluated
    generated = [c for c in calls if c[0] == "generate" and c[c.index("--scene") + 1] == "strips16"]
    assert ["300", "1"] in [[c[c.index("--n") + 1], c[c.index("--seed") + 1]] for c in generated]


def test_skip_train_only_benchmarks_and_a_failing_step_stops_the_demo(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = _record(monkeypatch)
    demo.run(argparse.Namespace(out=str(tmp_path / "d"), train_n=300, skip_train=True))
    assert not {"train", "export"} & {c[0] for c in calls}
    _record(monkeypatch, fail="eval")
    with pytest.raises(TactileError, match="demo step 'tactile-learn eval"):
        demo.run(argparse.Namespace(out=str(tmp_path / "d"), train_n=300, skip_train=True))
