"""Paths the tests share: the repository root (models/, scripts/, results/ and ../shared/ beside it)."""

from __future__ import annotations

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
