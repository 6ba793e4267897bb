"""scripts/strips_shrink.py: a smaller general strip network started from a larger trained one."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed: nothing here runs without it")

import torch

from synth.dataset import simulate_shard
from synth.errors import ConfigError
from synth.scene import load_scene
from tactile_learn.checkpoints import build_net, load_weights

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "scripts"))
import strips_shrink


def test_the_shrunk_network_loads_as_the_smaller_size_and_keeps_the_used_channels(tmp_path: Path) -> None:
    out = tmp_path / "tiny.pt"
    assert strips_shrink.main(["models/strips16.pt", "--size", "tiny", "--out", str(out)]) == 0
    saved = load_weights(out)
    scene = load_scene("strips16")
    net = build_net(saved, scene)  # strict load: every tensor has the tiny network's shape
    readings = torch.from_numpy(simulate_shard(scene, 4, 0, 16)["readings"])
    with torch.inference_mode():
        maps = net(readings).numpy()
    assert maps.shape == (16, 16, 16) and np.all(np.isfinite(maps)) and maps.max() > 0
    # a hidden channel the first block does not read is never kept
    source = load_weights("models/strips16.pt")
    state = {k: v.clone() for k, v in source["state_dict"].items()}
    for key in ("blocks.0.own.weight", "blocks.0.along_rows.weight", "blocks.0.along_cols.weight"):
        state[key][:, 3] = 0.0
    hidden = int(state["head.weight"].shape[1])  # the pooled inputs: [max (hidden), mean (hidden)]
    state["blocks.0.along_rows.weight"][:, hidden + 3] = 0.0
    state["blocks.0.along_cols.weight"][:, hidden + 3] = 0.0
    shrunk = strips_shrink.shrink(state, "tiny", blocks_from=2)
    kept = shrunk["crossings.physics_proj.weight"]
    assert not any(torch.equal(kept[i], state["crossings.physics_proj.weight"][3]) for i in range(len(kept)))


def test_shrinking_refuses_what_cannot_be_shrunk(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="other base"):
        strips_shrink.main(["models/strips16.pt", "--size", "tiny_law", "--out", str(tmp_path / "x.pt")])
    with pytest.raises(ConfigError, match="mixing blocks"):
        strips_shrink.main(["models/strips16.pt", "--size", "large", "--out", str(tmp_path / "x.pt")])
