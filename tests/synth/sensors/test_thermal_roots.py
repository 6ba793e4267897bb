"""The contact model's cubic roots in closed form (synth.sensors.thermal.physics) against the
companion-matrix eigenvalues they replaced, over parameters wider than any scene's."""

from __future__ import annotations

import numpy as np
import pytest

from synth.sensors.thermal.physics import _cubic, _direct_roots, _polish, _roots


def _eigen_roots(coef: np.ndarray) -> np.ndarray:
    a = coef[..., 1:] / coef[..., :1]
    comp = np.zeros((*a.shape[:-1], 3, 3))
    comp[..., 0, :] = -a
    comp[..., 1, 0] = 1.0
    comp[..., 2, 1] = 1.0
    return _polish(np.linalg.eigvals(comp).astype(np.complex128), a)


def _match(found: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """Largest distance of each expected root to the nearest found one, relative to the largest root."""
    dist = np.abs(found[:, :, None] - expected[:, None, :]).min(axis=1)
    return dist.max(axis=1) / np.abs(expected).max(axis=1)


@pytest.mark.parametrize("seed", [0, 1])
def test_closed_form_roots_are_the_eigenvalues(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 20_000
    c = rng.uniform(20.0, 5000.0, n)
    g = np.where(rng.random(n) < 0.3, 0.0, rng.uniform(0.0, 400.0, n))
    h = np.exp(rng.uniform(np.log(50.0), np.log(1e7), n))
    e = np.exp(rng.uniform(np.log(30.0), np.log(40000.0), n))
    ks = np.where(rng.random(n) < 0.3, 0.0, rng.uniform(0.0, 3000.0, n))
    coef = _cubic(c, g, h, e, ks)
    found, expected = _roots(coef), _eigen_roots(coef)
    assert np.isfinite(found).all()
    # every root found (a distance relative to the largest root: the eigen-solver's own accuracy)
    assert _match(found, expected).max() < 1e-12
    # the closed form itself (before the eigen-solver's fallback) finds nearly all of them; a root
    # at 0 (G = k_s = 0, the seed's model: a3 = 0) is left to the eigen-solver
    a = coef[:, 1:] / coef[:, :1]
    with np.errstate(all="ignore"):
        direct = _polish(_direct_roots(a), a)
    alone = np.isfinite(direct).all(axis=1) & (_match(direct, expected) < 1e-12)
    assert alone[a[:, 2] != 0].mean() > 0.999
    # the cases the closed form treats apart do occur: three real roots and a complex pair
    real = (found.imag == 0).all(axis=1)
    assert real.any() and (~real).any()


def test_roots_keep_the_batch_shape_and_a_scalar_cubic() -> None:
    c, g, h, e, ks = np.broadcast_arrays(np.array([[2000.0, 20.0]]), 250.0, 1e4, np.array([[1000.0, 30.0]]), 500.0)
    coef = _cubic(c, g, h, e, ks)
    assert _roots(coef).shape == (1, 2, 3)
    single = _cubic(*(np.array(x) for x in (2000.0, 250.0, 1e4, 1000.0, 500.0)))
    assert _roots(single).shape == (3,)
    assert _match(_roots(single)[None], _eigen_roots(single)[None]).max() < 1e-12


def test_a_double_root_falls_back_to_the_eigen_solver() -> None:
    # (q + 1)^2 (q + 2): the closed form's pair from a zero discriminant fails Vieta's check or not;
    # either way the roots must be those of the cubic
    coef = np.array([[1.0, 4.0, 5.0, 2.0], [1.0, 3.0, 3.0, 1.0]])
    found = _roots(coef)
    assert np.isfinite(found).all()
    assert _match(found, np.array([[-1.0, -1.0, -2.0], [-1.0, -1.0, -1.0]], dtype=complex)).max() < 1e-5
