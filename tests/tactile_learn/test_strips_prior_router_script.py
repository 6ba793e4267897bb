"""scripts/strips_prior_router.py: the router trains on library and generic frames, and the routed model
answers each frame with the model of the side the router picks."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from synth.dataset import generate
from synth.scene import load_scene
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_prior_router as router
import strips_product_fields as products
import strips_random_shapes as shapes


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("prior")
    generate(load_scene("strips16_wide"), 120, 1, root / "wide")
    shapes.write(120, 2, root / "shapes")
    products.write(60, 3, root / "products")
    patch = pytest.MonkeyPatch()
    patch.setattr(router, "LIBRARY", {str(root / "wide"): 120})
    patch.setattr(router, "GENERIC", {str(root / "shapes"): 120, str(root / "products"): 60})
    # the generic side answered by another shipped model, so that the two sides give different maps
    patch.setattr(router, "MODELS", {"library": "models/strips16.onnx", "generic": "models/strips16_small.onnx"})
    card = router.train(root / "router", log=lambda *a: None)
    patch.undo()
    assert 0.0 <= card["held_out_accuracy"] <= 1.0 and card["threshold"] == 0.5
    return root


def test_the_router_card_names_its_frames_and_models(trained: Path) -> None:
    card = json.loads((trained / "router" / "router.json").read_text())
    assert set(card["library"]) == {str(trained / "wide")} and len(card["generic"]) == 2
    assert (trained / "router" / "router.onnx").is_file() and len(card["mean"]) == 33


def test_each_frame_is_answered_by_the_model_of_its_side(trained: Path) -> None:
    routed = router.PriorRouted(trained / "router")
    frames = np.concatenate(
        [
            shapes.draw(shapes.shapes_scene(), 40, np.random.default_rng(5))["readings"],
            products.draw(products.product_scene(), 40, np.random.default_rng(6))["readings"],
        ]
    )
    generic = routed.generic(frames)
    assert generic.dtype == bool and generic.shape == (80,)
    out = routed.predict(frames)
    for side, mask in (("generic", generic), ("library", ~generic)):
        if mask.any():
            np.testing.assert_array_equal(out[mask], routed.models[side].predict(frames[mask]))
    # the two sides answer differently, so the check above could fail
    assert not np.array_equal(routed.models["generic"].predict(frames), routed.models["library"].predict(frames))
