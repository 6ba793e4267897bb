"""nets/strips_consistent.py's separable form: the same ISRA step as the dense forward model.

The reference here is the step written with the dense float64 operators of the physics
(``cell_stress_operators``), as the step was first written."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch", reason="torch (training extra) is not installed: nothing here runs without it")

import torch

from synth.dataset import simulate_shard
from synth.errors import ModelError
from synth.scene import load_scene
from synth.sensors.strips import StripSensor
from tactile_learn.checkpoints import load_weights
from tactile_learn.nets.strips_consistent import RATIO_CAP, RATIO_EPS, ConsistencyStep, kronecker_factors
from tactile_learn.nets.strips_general import GeneralStripNet, GeneralStripNetWithResidual, StripForward

N = 16


@pytest.fixture(scope="module")
def physics() -> dict[str, np.ndarray]:
    """The strips16 scene's dense float64 operators (cells -> row and column segments)."""
    k_row, k_col = StripSensor(load_scene("strips16").sensor).array.cell_stress_operators()
    return {"k_row": k_row, "k_col": k_col, "stress": np.concatenate([k_row.T, k_col.T], axis=1)}


def dense_step(
    maps: np.ndarray, loads: np.ndarray, stress: np.ndarray, sums: np.ndarray, p0: float, exponent: float
) -> tuple[np.ndarray, np.ndarray]:
    """The ISRA step and the model loads with dense operators in float64."""
    x = maps.reshape(len(maps), -1).astype(np.float64)
    s = np.maximum(x @ stress, 0.0)
    gain = 1.0 - (1.0 + s / p0) ** -exponent
    model = gain @ sums
    slope = (1.0 - gain) ** ((exponent + 1.0) / exponent)
    numerator = ((loads @ sums.T) * slope) @ stress.T + RATIO_EPS
    denominator = ((model @ sums.T) * slope) @ stress.T + RATIO_EPS
    return (x * np.minimum(numerator / denominator, RATIO_CAP)).reshape(maps.shape), model


def probe_maps(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Maps (kPa) and measured loads covering the cases: simulated contacts, random non-negative
    maps, an empty map, a map with one lit cell, saturating pressures (gains near 1) and loads at
    the strips' largest value; loads both unlike (noise, scaled) and like the maps' own."""
    scene = load_scene("strips16")
    rng = np.random.default_rng(seed)
    arrays = simulate_shard(scene, 700 + seed, 0, 8)
    loads = StripSensor(scene.sensor).invert_readings(arrays["readings"])
    maps = [arrays["pressure"].astype(np.float64)]
    maps.append(rng.gamma(0.3, 40.0, size=(4, N, N)))
    one = np.zeros((1, N, N))
    one[0, 3, 11] = 250.0
    maps += [np.zeros((2, N, N)), one, rng.uniform(2e3, 2e4, size=(2, N, N))]
    stacked = np.concatenate(maps)
    measured = np.concatenate(
        [
            loads,
            loads[:4] * rng.uniform(0.5, 1.5, size=(4, 2 * N)),
            np.zeros((1, 2 * N)),  # an empty map with empty readings
            loads[:1],  # an empty map with a contact in the readings: the ratio's cap
            loads[1:2],
            np.full((2, 2 * N), float(N)),  # every segment saturated
        ]
    )
    return stacked, measured


def test_factors_reproduce_the_physics_operators(physics: dict[str, np.ndarray]) -> None:
    """From the float32 matrices the model carries, a few terms per layer rebuild the float64
    operators as closely as the float32 matrices themselves do."""
    forward = StripForward(load_scene("strips16"))
    dense32 = forward.stress.double().numpy()
    for layer, exact in enumerate((physics["k_row"], physics["k_col"])):
        a, b = kronecker_factors(dense32[:, layer * N * N : (layer + 1) * N * N].T, N, N)
        rebuilt = np.einsum("rik,rjl->ijkl", a, b).reshape(N * N, N * N)
        scale = np.abs(exact).max()
        own_rounding = np.abs(dense32[:, layer * N * N : (layer + 1) * N * N].T - exact).max()
        assert len(a) < 5  # fewer terms than the physics' kernel (its fifth is below float32)
        assert np.abs(rebuilt - exact).max() <= own_rounding + 2.0**-24 * scale


def test_factors_take_the_fewest_terms() -> None:
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(2, 3, 3)), rng.normal(size=(2, 5, 5))
    operator = np.kron(a[0], b[0]) + np.kron(a[1], b[1])
    got_a, got_b = kronecker_factors(operator, 3, 5)
    assert got_a.shape == (2, 3, 3) and got_b.shape == (2, 5, 5)
    np.testing.assert_allclose(np.einsum("rik,rjl->ijkl", got_a, got_b).reshape(15, 15), operator, atol=1e-12)
    assert len(kronecker_factors(operator, 3, 5, min_terms=3)[0]) == 3
    # any operator is a sum of at most min(N^2, M^2) such terms
    assert len(kronecker_factors(rng.normal(size=(15, 15)), 3, 5)[0]) == 9
    with pytest.raises(ModelError, match="shape"):
        kronecker_factors(np.eye(12), 4, 4)


@pytest.mark.parametrize("exponent", [1.0, 1.6])
def test_the_separable_step_equals_the_dense_one(physics: dict[str, np.ndarray], exponent: float) -> None:
    """float64: equal to the dense float64 step to the float32 rounding of the factors it carries;
    float32: no further from it than the dense float32 step (the shipped form before) is."""
    forward = StripForward(load_scene("strips16"))
    forward.exponent = exponent  # the law's general branch (the scene's own is n = 1)
    maps, loads = probe_maps(1)
    want, want_model = dense_step(maps, loads, physics["stress"], forward.sums.double().numpy(), forward.p0, exponent)
    step = ConsistencyStep(forward)
    with torch.inference_mode():
        got64, model64 = step.double().step(torch.from_numpy(maps), torch.from_numpy(loads))
        got32, model32 = step.float().step(torch.from_numpy(maps).float(), torch.from_numpy(loads).float())
    # the dense float32 step (float32 matrices and arithmetic), as it shipped
    stress32 = forward.stress.numpy()
    old32, _ = dense_step(
        maps.astype(np.float32), loads.astype(np.float32), stress32, forward.sums.numpy(), forward.p0, exponent
    )
    scale = np.abs(want).max(axis=(1, 2), keepdims=True) + 1e-30
    np.testing.assert_allclose(got64.numpy() / scale, want / scale, rtol=0, atol=2e-6)
    load_scale = np.abs(want_model).max(axis=1, keepdims=True) + 1e-30
    np.testing.assert_allclose(model64.numpy() / load_scale, want_model / load_scale, rtol=0, atol=1e-6)
    err32 = np.abs(got32.numpy() - want) / scale
    err_old = np.abs(old32 - want) / scale
    assert err32.max() <= 2.0 * err_old.max() + 1e-6
    np.testing.assert_allclose(model32.numpy() / load_scale, want_model / load_scale, rtol=0, atol=1e-5)
    for got in (got64, got32):
        assert torch.isfinite(got).all() and (got >= 0).all()
    assert float(got32[maps.sum(axis=(1, 2)) == 0].abs().max()) == 0.0  # empty maps stay empty


def test_the_gradient_is_the_dense_steps(physics: dict[str, np.ndarray]) -> None:
    """Training backpropagates through the step: its gradient equals the dense step's (float64) on
    lit cells. On an empty cell the gradient is the ratio itself, a quotient of two back-projections
    at 1e-4 of their largest value there, which the factors' float32 rounding (absolute, ~3e-8 of
    the largest entry) moves by up to 4e-4 of itself: a few 1e-4 of the largest gradient."""
    forward = StripForward(load_scene("strips16"))
    maps, loads = probe_maps(2)
    maps, loads = maps[:12], loads[:12]  # not the saturated frames (their gradient is ~0 either way)
    stress = torch.from_numpy(physics["stress"])
    sums = forward.sums.double()
    weights = torch.from_numpy(np.random.default_rng(3).normal(size=maps.shape))

    def dense(x: torch.Tensor) -> torch.Tensor:
        s = x.reshape(len(x), -1) @ stress
        gain = s / (s + forward.p0)
        slope = (1.0 - gain) ** 2
        numerator = ((torch.from_numpy(loads) @ sums.T) * slope) @ stress.T + RATIO_EPS
        denominator = (((gain @ sums) @ sums.T) * slope) @ stress.T + RATIO_EPS
        return (x.reshape(len(x), -1) * (numerator / denominator).clamp(max=RATIO_CAP)).reshape(x.shape)

    step = ConsistencyStep(forward).double()
    grads = []
    for fn in (dense, lambda x: step(x, torch.from_numpy(loads))):
        x = torch.from_numpy(maps).requires_grad_(True)
        (fn(x) * weights).sum().backward()
        assert x.grad is not None
        grads.append(x.grad.numpy())
    lit = maps > 0
    largest = np.abs(grads[0]).max()
    np.testing.assert_allclose(grads[1][lit], grads[0][lit], rtol=1e-5, atol=1e-7 * largest)
    np.testing.assert_allclose(grads[1], grads[0], rtol=0, atol=1e-3 * largest)


def test_the_exported_step_equals_torch_and_carries_no_dense_operator(tmp_path: Path) -> None:
    """The deployed graph of a network with the step (random head, the shipped statistics) under
    onnxruntime: the map, residual and balance of the float64 training module to float32 rounding,
    and no initializer as large as one dense stress operator (256 x 256 floats)."""
    import onnx
    import onnxruntime as ort

    from tactile_learn.export import to_onnx
    from tactile_learn.nets.strips_deploy import deploy

    scene = load_scene("strips16")
    shipped = load_weights("models/strips16.pt")
    torch.manual_seed(5)
    net = GeneralStripNet(scene, shipped["stats"], "wide_consistent")
    with torch.no_grad():
        net.head.weight.normal_(0.0, 0.1)
    net.eval()
    readings = simulate_shard(scene, 4321, 0, 64)["readings"].astype(np.float32)
    deployed = deploy(net, scene, torch.from_numpy(readings))
    path = tmp_path / "step.onnx"
    to_onnx(deployed, torch.from_numpy(readings[:2]), path, "readings", ["pressure", "residual", "balance"], {})
    largest = max(int(np.prod(t.dims)) for t in onnx.load(str(path)).graph.initializer)
    assert largest < N**4
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    with torch.inference_mode():
        want = GeneralStripNetWithResidual(copy.deepcopy(net).double(), scene).double()(
            torch.from_numpy(readings).double()
        )
    for batch in (1, 64):
        got = session.run(None, {"readings": readings[:batch]})
        for g, w in zip(got, want, strict=True):
            w = w[:batch].numpy()
            np.testing.assert_allclose(g, w, rtol=1e-4, atol=1e-4 * max(float(np.abs(w).max()), 1.0))
