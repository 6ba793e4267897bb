"""scripts/strips_grow.py: a deeper or wider general strip network started from a trained one."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed: nothing here runs without it")

import torch

from synth.dataset import simulate_shard
from synth.errors import ConfigError
from synth.scene import load_scene, parse_scene
from tactile_learn.checkpoints import build_net, load_torch, load_weights, save_torch
from tactile_learn.nets.strips_general import GeneralStripNet

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "scripts"))
import strips_grow


def _small_source(folder: Path, size: str = "small") -> Path:
    """A general network of ``size`` (default small) with random weights (every layer, the head too, so that each
    one shapes the map) and the shipped default's statistics, with its scene: the source to grow."""
    shipped = load_weights("models/strips16.pt")
    torch.manual_seed(7)
    net = GeneralStripNet(load_scene("strips16"), shipped["stats"], size)
    with torch.no_grad():
        net.head.weight.normal_(0.0, 0.1)
    path = folder / f"{size}.pt"
    scene = load_scene("strips16").to_dict()
    save_torch(
        path,
        {"task": "strips", "size": size, "scene": scene, "stats": shipped["stats"], "state_dict": net.state_dict()},
    )
    return path


def test_the_grown_network_computes_what_the_trained_one_does_and_can_learn(tmp_path: Path) -> None:
    out, small = tmp_path / "deep.pt", _small_source(tmp_path)
    assert strips_grow.main([str(small), "--size", "deep", "--out", str(out)]) == 0
    scene = load_scene("strips16")
    grown = build_net(load_weights(out), scene)  # strict load: three mixing blocks
    source = build_net(load_weights(small), scene)
    assert len(grown.blocks) == len(source.blocks) + 1
    readings = torch.from_numpy(simulate_shard(scene, 4, 0, 32)["readings"])
    with torch.inference_mode():
        np.testing.assert_allclose(grown(readings).numpy(), source(readings).numpy(), rtol=1e-5, atol=1e-4)
    # the added block is not a dead end: the loss has a gradient on its weights
    grown.train()
    grown(readings).pow(2).mean().backward()
    added = grown.blocks[-1]
    assert float(added.own.weight.grad.abs().sum()) > 0.0
    assert float(added.along_rows.weight.grad.abs().sum()) > 0.0


def test_the_widened_network_computes_what_the_trained_one_does_and_exports(tmp_path: Path) -> None:
    out, small = tmp_path / "wide.pt", _small_source(tmp_path)
    assert strips_grow.main([str(small), "--size", "wide", "--out", str(out)]) == 0
    scene = load_scene("strips16")
    widened = build_net(load_weights(out), scene)  # strict load: 24 crossing channels
    source = build_net(load_weights(small), scene)
    assert widened.head.weight.shape[1] == 24 and source.head.weight.shape[1] == 16
    readings = torch.from_numpy(simulate_shard(scene, 4, 0, 32)["readings"])
    with torch.inference_mode():
        np.testing.assert_allclose(widened(readings).numpy(), source(readings).numpy(), rtol=1e-5, atol=1e-4)
    # the added channels carry features (fresh weights into them), so the weights reading them learn
    widened.train()
    widened(readings).pow(2).mean().backward()
    assert float(widened.head.weight.grad[:, 16:].abs().sum()) > 0.0
    assert float(widened.blocks[-1].own.weight.grad[:16, 16:].abs().sum()) > 0.0
    # the exported form of the wider network is checked against it (deploy refuses a difference)
    from tactile_learn.nets.strips_deploy import deploy

    deploy(widened.eval(), scene, readings)


def test_a_narrower_target_is_refused() -> None:
    state = load_weights("models/strips16.pt")["state_dict"]
    narrow = dict(state)
    narrow["head.weight"] = state["head.weight"][:, :8]
    with pytest.raises(ConfigError, match="fewer than the source"):
        strips_grow.widen(state, narrow)


def test_only_the_number_of_blocks_may_grow(tmp_path: Path) -> None:
    small = _small_source(tmp_path)
    with pytest.raises(ConfigError, match="only the number of mixing blocks"):
        strips_grow.main([str(small), "--size", "large", "--out", str(tmp_path / "x.pt")])
    with pytest.raises(ConfigError, match="fewer mixing blocks"):
        strips_grow.grow(load_weights(small)["state_dict"], "small", "deep")


def test_the_wider_context_computes_what_the_trained_one_does_and_can_learn(tmp_path: Path) -> None:
    """context384_consistent from a wide_consistent network: the added context units change nothing
    until trained, and the weights reading them have a gradient."""
    out, source_path = tmp_path / "context.pt", _small_source(tmp_path, "wide_consistent")
    assert strips_grow.main([str(source_path), "--size", "context384_consistent", "--out", str(out)]) == 0
    scene = load_scene("strips16")
    grown = build_net(load_weights(out), scene)  # strict load: 384 context units
    source = build_net(load_weights(source_path), scene)
    assert grown.context[2].weight.shape == (384, 384) and source.context[2].weight.shape == (192, 192)
    assert grown.consistency is not None
    readings = torch.from_numpy(simulate_shard(scene, 4, 0, 32)["readings"])
    with torch.inference_mode():
        np.testing.assert_allclose(grown(readings).numpy(), source(readings).numpy(), rtol=1e-5, atol=1e-4)
    grown.train()
    grown(readings).pow(2).mean().backward()
    assert float(grown.context[4].weight.grad[:, 192:].abs().sum()) > 0.0


def test_two_dimensions_at_once_are_refused(tmp_path: Path) -> None:
    source = _small_source(tmp_path, "wide_consistent")
    with pytest.raises(ConfigError, match="alone"):
        strips_grow.main([str(source), "--size", "large", "--out", str(tmp_path / "x.pt")])
    with pytest.raises(ConfigError, match="fewer than the source"):
        state = load_weights(source)["state_dict"]
        strips_grow.widen_context(state, {**state, "context.2.weight": state["context.2.weight"][:96, :96]})


def test_growing_a_shipped_model_writes_its_scene_for_train_init(tmp_path: Path) -> None:
    """A shipped NAME.pt keeps its scene in the card beside it; the grown file must carry it itself,
    and the grown network computes what the shipped one does."""
    assert "scene" not in load_torch("models/strips16.pt")
    out = tmp_path / "wide28.pt"
    assert strips_grow.main(["models/strips16.pt", "--size", "wide28_consistent", "--out", str(out)]) == 0
    card = json.loads(Path("models/strips16.json").read_text())
    assert parse_scene(load_torch(out)["scene"]).digest == card["scene_digest"]
    scene = load_scene("strips16")
    readings = torch.from_numpy(simulate_shard(scene, 5, 0, 16)["readings"])
    with torch.inference_mode():
        expected = build_net(load_weights("models/strips16.pt"), scene)(readings).numpy()
        # built from the file alone: its own scene
        np.testing.assert_allclose(build_net(load_weights(out))(readings).numpy(), expected, atol=1e-4)
