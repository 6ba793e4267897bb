"""Where a recorded figure came from, as a model card or a results file may show it: paths made
portable (never a path of the machine that wrote them) and a dataset's generating parameters."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path
from typing import Any

__all__ = ["command_line", "dataset_record", "portable_path"]


def portable_path(path: str | Path) -> str:
    """``path`` as it may appear in a shipped card: relative to the working folder when inside it,
    else only its name (a card never records a path of the machine it was made on)."""
    p = Path(path)
    if not p.is_absolute():
        return p.as_posix()
    try:
        return p.resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return p.name


def dataset_record(path: str | Path, n_frames: int) -> dict[str, Any]:
    """A held-out dataset as a card records it: its path, and the scene, seed and size it was
    generated with (from its manifest), so that ``tactile-learn cards verify`` can regenerate it.
    A folder without a manifest (recordings, an ``.npz``) records its path and frame count only."""
    record: dict[str, Any] = {"path": portable_path(path), "seed": None}
    manifest = Path(path) / "manifest.json"
    if manifest.is_file():
        meta = json.loads(manifest.read_text())
        scene = meta.get("scene")
        record.update(
            scene=scene.get("name") if isinstance(scene, dict) else scene,
            scene_digest=meta.get("scene_digest"),
            seed=meta.get("seed"),
            n=meta.get("n"),
            shard_size=meta.get("shard_size"),  # a shard's bytes depend on it
        )
    record["n_frames"] = n_frames
    return record


def command_line(prog: str = "tactile-learn") -> str:
    """This process's command line with portable paths (what a card says measured its figures)."""
    args = [portable_path(a) if Path(a).is_absolute() else a for a in sys.argv[1:]]
    return prog + " " + " ".join(shlex.quote(a) for a in args)
