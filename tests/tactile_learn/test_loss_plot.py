"""The training run's loss plot: a log axis where it can be drawn, a linear one where it cannot."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed")
pytest.importorskip("matplotlib", reason="matplotlib (plots extra) is not installed")

from tactile_learn.train import _loss_plot


def _history(losses: list[float]) -> list[dict[str, object]]:
    return [{"epoch": i + 1, "train_loss": loss, "val": {"r": 0.5}} for i, loss in enumerate(losses)]


@pytest.mark.parametrize("losses", [[0.3, 0.1, 0.05], [0.0, 0.0]])
def test_loss_plot_draws_without_warnings(tmp_path: Path, losses: list[float]) -> None:
    path = tmp_path / "loss.png"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # matplotlib warns when a log axis gets a zero
        assert _loss_plot(_history(losses), path, "r")
    assert path.stat().st_size > 1000
