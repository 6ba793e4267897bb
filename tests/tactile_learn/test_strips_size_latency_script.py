"""scripts/strips_size_latency.py: a size's untrained network is the shipped architecture of that
size, exported and loaded as a shipped model is; bad sizes are refused with a clear error."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed: nothing here runs without it")

from synth.dataset import simulate_shard
from synth.errors import ConfigError
from tactile_learn.methods import shipped_models
from tactile_learn.runtime import OnnxEstimator, read_card
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_size_latency


@pytest.mark.parametrize("text", ["24,24,192", "24,24,192,2,x", "24,0,192,2", "a,b,c,d"])
def test_a_malformed_size_is_refused(text: str) -> None:
    with pytest.raises(ConfigError, match="ENC,HIDDEN,CONTEXT,BLOCKS"):
        strips_size_latency.parse_size(text)


def test_the_shipped_size_gives_the_shipped_graph_and_parameters(tmp_path: Path) -> None:
    path = strips_size_latency.untrained_model("24,24,192,2,c", tmp_path, seed=0)
    shipped = shipped_models("strips")["strips16"]
    assert read_card(path)["network"]["parameters"] == read_card(shipped)["network"]["parameters"]
    # the same graph as the shipped weights exported now, up to weights: the same nodes in `predict`'s graph
    import onnx
    import torch

    from tactile_learn.export import to_onnx
    from tactile_learn.onnx_prune import first_output_graph
    from tactile_learn.tasks import get_task
    from tactile_learn.torch_estimator import TorchEstimator

    trained = TorchEstimator.from_checkpoint(shipped.with_suffix(".pt"), threads=1)
    graph, names = get_task("strips").export_module(trained.net, trained.scene)
    now = tmp_path / "shipped_now.onnx"
    example = torch.from_numpy(simulate_shard(trained.scene, 5, 0, 2)["readings"])
    to_onnx(graph.eval(), example, now, "readings", names, {"task": "strips"})

    def kinds(graph_path: Path) -> list[str]:
        cut = first_output_graph(graph_path)
        assert cut is not None
        return sorted(n.op_type for n in onnx.load_from_string(cut).graph.node)

    assert kinds(path) == kinds(now)
    model = OnnxEstimator(path, threads=1).prepare()
    frames = simulate_shard(model.card_scene_, 5, 0, 3)["readings"].astype(np.float32)
    out = model.predict(frames)
    assert out.shape == (3, 16, 16) and np.all(np.isfinite(out)) and np.all(out >= 0)
