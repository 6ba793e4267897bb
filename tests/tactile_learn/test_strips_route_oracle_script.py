"""scripts/strips_route_oracle.py: the frame-by-frame oracle between a routed card's two members bounds the
routed card and each member from above, and an unrouted card is refused."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.scene import load_scene
from tactile_learn.methods import resolve_method
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_route_oracle as oracle

MODELS = REPO_ROOT / "models"


def test_the_oracle_bounds_the_routed_card_and_each_member() -> None:
    members = oracle.members_of(MODELS / "strips16.onnx")
    arrays = simulate_shard(load_scene("strips16_mixed"), 21, 0, 120)
    readings = np.asarray(arrays["readings"], dtype=np.float32)
    truth = np.asarray(arrays["pressure"], dtype=np.float32)
    rules = {"intersection": resolve_method("strips", "intersection", load_scene("strips16"))}
    m = oracle.family_margins(members, readings, truth, rules)
    assert set(m) == set(oracle.KINDS)
    assert m["frame_oracle"] >= max(m["own"], m["generic"], m["routed"]) - 1e-9
    assert m["own"] != m["generic"]  # two different networks: the bound can be strict
    assert m["frame_oracle"] > min(m["own"], m["generic"])


def test_a_card_without_a_route_is_refused() -> None:
    with pytest.raises(SystemExit, match="routes no frames"):
        oracle.members_of(MODELS / "strips16_small.onnx")


def test_the_cli_writes_every_suite_asked_for(tmp_path: Path) -> None:
    out = tmp_path / "o.json"
    assert oracle.main(["strips16_ood", "--seeds", "1", "--n", "4", "--json", str(out)]) == 0
    result = json.loads(out.read_text())["suites"]["strips16_ood"]
    assert len(result["families"]) == 11 and set(result["mean"]) == set(oracle.KINDS)


@pytest.mark.parametrize("logit, soft_is", [(60.0, "generic"), (-60.0, "own")])
def test_blends_at_their_ends_are_the_members_and_soft_routing_follows_the_router(
    monkeypatch: pytest.MonkeyPatch, logit: float, soft_is: str
) -> None:
    members = oracle.members_of(MODELS / "strips16.onnx")
    arrays = simulate_shard(load_scene("strips16_mixed"), 22, 0, 60)
    readings = np.asarray(arrays["readings"], dtype=np.float32)
    truth = np.asarray(arrays["pressure"], dtype=np.float32)
    rules = {"intersection": resolve_method("strips", "intersection", load_scene("strips16"))}
    route = members["routed"].route_
    assert route is not None
    # a router sure of every frame: soft routing is then that member's map
    monkeypatch.setattr(route[0], "logit", lambda x: np.full(len(x), logit, dtype=np.float32))
    monkeypatch.setattr(oracle, "BLENDS", (0.0, 0.5, 1.0))
    m = oracle.family_margins(members, readings, truth, rules)
    assert m["blend_0.0"] == pytest.approx(m["own"], abs=1e-12)
    assert m["blend_1.0"] == pytest.approx(m["generic"], abs=1e-12)
    assert m["soft"] == pytest.approx(m[soft_is], abs=1e-12)
    assert m["blend_0.5"] not in (m["own"], m["generic"])
