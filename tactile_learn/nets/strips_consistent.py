"""One consistency step through the forward model: make a strip map explain its readings.

A network's map (B, N, M) predicts strip loads through the sensor's forward model
(:class:`~tactile_learn.nets.strips_general.StripForward`: cover kernel, piezoresistive law,
cell-constant pressure); where they differ from the measured loads, one multiplicative step of
ISRA (the image-space reconstruction algorithm, the iteration of the classical ``projection``
estimator) moves the map towards maps that explain them:

    x <- x * (J^T L) / (J^T L_model(x)),   J = dL_model / dx >= 0

It keeps the map non-negative and its dark cells dark, and changes what the network decided
(which crossings are ghosts) only through the strips' totals: a crossing whose strips carry more
load than the map explains grows, one whose strips carry less shrinks. ``J``'s factor ``n / p0``
cancels in the ratio, so the step needs the segments' ``(1 - f)^((n + 1) / n)`` only.

Measured after the fact on the shipped wide network's maps (no training; the ood suite and two
independent draws of it): one step lifts the margin over the best classical method by 0.002 (0.048
-> 0.050 on all three draws) and two spheres by 0.001; more steps or the additive (Gauss-Newton)
projection gain less on the block at 30 degrees (docs/strips.md, "A consistency step").

**Separable form.** The forward model's stress operators are dense ``(N*M, N*M)`` matrices per
layer, but the physics builds each as a short sum of separable terms (``synth``'s
``cell_stress_operators``: ``stress = sum_r A_r X B_r^T``, the cover kernel's SVD). The step
recovers such factors from the dense float32 matrices themselves (:func:`kronecker_factors`, Van
Loan and Pitsianis' rearrangement and SVD, keeping the fewest terms that reproduce every entry to
within float32's unit roundoff of the largest, checked) and applies the operator and its
transpose as two small matrix products each. On the strips16 scene 4 terms per layer reproduce the
float32 operators to 2.7e-8 of their largest entry (the dense float32 matrices themselves differ
from the float64 operators by 3.5e-8): the same function to float32 rounding, without the two
0.5 MB matrices (measured in ``scripts/strips_step_bench.py``). The rounding is absolute, not per
entry: on an empty cell (``x = 0``, output 0 either way) the ratio, a quotient of two
back-projections at 1e-4 of their largest value, moves by up to 4e-4 of itself; on lit cells by
3.5e-7. Stresses are laid out
``(row i, layer, column j)``: the stage that contracts the column index is then one matrix
product of all rows, frames and layers with a constant block-diagonal matrix.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

from synth.errors import ModelError
from tactile_learn.nets.strip_blocks import law_gain

__all__ = ["FACTOR_TOL", "RATIO_CAP", "RATIO_EPS", "ConsistencyStep", "kronecker_factors"]

#: the step's largest factor on a cell. Dark cells far from any contact see ratios of noise over
#: a near-zero model load (up to ~50 on two-sphere frames); capped so that their gradient stays
#: bounded in training. No lit cell comes near it (99th percentile of the mass-weighted ratio 1.2,
#: 2.0 on a diagonal edge), and r is unchanged by the cap on the suite.
RATIO_CAP = 10.0
#: added to both sides of the ratio: 0 / 0 on a cell no strip is sensitive to gives 1 (the map kept)
RATIO_EPS = 1e-6
#: the separable factors reproduce every entry of a dense operator to this fraction of its largest
#: entry: float32's unit roundoff, the precision the dense float32 operator is known to
FACTOR_TOL = 2.0**-24


def kronecker_factors(
    operator: np.ndarray, n: int, m: int, tol: float = FACTOR_TOL, min_terms: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Factors ``A (R, N, N)``, ``B (R, M, M)`` (float64) of a ``(N*M, N*M)`` operator on row-major
    ``(N, M)`` maps, ``operator = sum_r kron(A_r, B_r)`` (row-major ``vec(A X B^T) = (A kron B)
    vec(X)``), with the fewest terms (at least ``min_terms``) that reproduce every entry to ``tol``
    of the largest.

    The operator's entries rearranged as ``((i, k), (j, l))`` form a matrix whose rank-R SVD is the
    best R-term sum in Frobenius norm (Van Loan and Pitsianis); :class:`ModelError` when no R
    reaches ``tol`` (an operator that is not a short sum of separable terms)."""
    op = np.asarray(operator, dtype=np.float64)
    if op.shape != (n * m, n * m):
        raise ModelError(f"stress operator: expected shape ({n * m}, {n * m}), got {op.shape}")
    rearranged = op.reshape(n, m, n, m).transpose(0, 2, 1, 3).reshape(n * n, m * m)
    u, sigma, vt = np.linalg.svd(rearranged, full_matrices=False)
    scale = float(np.abs(op).max()) or 1.0
    # the rearrangement permutes entries: the residual of the truncated SVD is the operator's error
    residual = rearranged.copy()
    for rank in range(1, len(sigma) + 1):
        residual -= sigma[rank - 1] * np.outer(u[:, rank - 1], vt[rank - 1])
        if rank >= min_terms and np.abs(residual).max() <= tol * scale:
            root = np.sqrt(sigma[:rank])
            return (u[:, :rank] * root).T.reshape(rank, n, n), (vt[:rank] * root[:, None]).reshape(rank, m, m)
    raise ModelError(f"stress operator: no sum of separable terms reproduces it to {tol:g} of its largest entry")


class ConsistencyStep(nn.Module):
    """``(maps (B, N, M) kPa, measured loads (B, N + M)) -> maps``: one ISRA step (module docstring).

    ``forward``: the scene's ``StripForward`` (its matrices and law). The separable factors of its
    two stress operators are kept in buffers that are not saved with the weights (they follow from
    the scene): a network with the step loads the weights of the same network without it."""

    left: torch.Tensor
    left_t: torch.Tensor
    right: torch.Tensor
    right_t: torch.Tensor
    expand: torch.Tensor
    sums: torch.Tensor

    def __init__(self, forward: Any) -> None:
        super().__init__()
        stress = forward.stress.detach().cpu().double().numpy()  # (N*M cells, 2 N*M segments)
        n_cells = int(forward.n_cells)
        # row strip 0 collects row segments (0, 0..M-1): the array's shape from the sums
        m = int(forward.sums[:n_cells, 0].sum())
        n = n_cells // m
        self.n_rows, self.n_cols = n, m
        # per layer, segments (i, j) <- cells (k, l): the transposes of the two column blocks; both
        # layers share the products, so both take the larger number of terms
        blocks = [stress[:, k * n_cells : (k + 1) * n_cells].T for k in (0, 1)]
        rank = max(len(kronecker_factors(block, n, m)[0]) for block in blocks)
        (a_row, b_row), (a_col, b_col) = (kronecker_factors(block, n, m, min_terms=rank) for block in blocks)
        self.rank = rank
        a, b = np.stack([a_row, a_col]), np.stack([b_row, b_col])  # (2, R, N, N), (2, R, M, M)
        # stage 1, over the row index k: rows (i, layer, r), a constant left factor
        left = a.transpose(2, 0, 1, 3).reshape(n * 2 * rank, n)
        # stage 2, over (r, l) of each layer: block-diagonal, columns (layer, j)
        blocks_right = np.zeros((2, rank, m, 2, m))
        for layer in range(2):
            blocks_right[layer, :, :, layer, :] = b[layer].transpose(0, 2, 1)
        right = blocks_right.reshape(2 * rank * m, 2 * m)
        # segment (i, layer, j) -> its strip: row strip i (layer 0), column strip j (layer 1)
        owner = np.zeros((n, 2, m, n + m))
        owner[np.arange(n), 0, :, np.arange(n)] = 1.0
        owner[:, 1, np.arange(m), n + np.arange(m)] = 1.0
        sums = owner.reshape(2 * n * m, n + m)
        self.p0 = float(forward.p0)
        self.exponent = float(forward.exponent)
        # with n = 1 the slope (1 - f)^2 = p0^2 / (s + p0)^2: p0^2 rides on the strips' expansion
        spread = self.p0**2 if self.exponent == 1.0 else 1.0
        for name, array in (
            ("left", left),
            ("left_t", left.T),
            ("right", right),
            ("right_t", right.T),
            ("sums", sums),
            ("expand", sums.T * spread),
        ):
            self.register_buffer(
                name, torch.from_numpy(np.ascontiguousarray(array, dtype=np.float32)), persistent=False
            )

    def stress(self, x: torch.Tensor) -> torch.Tensor:
        """Segment stress (B, N, 2 M) (row i, layer, column j) of maps ``x`` (B, N, M)."""
        first = (self.left @ x).reshape(-1, self.n_rows, 2 * self.rank * self.n_cols)
        return first @ self.right

    def back(self, y: torch.Tensor) -> torch.Tensor:
        """``J^T``'s stress part: segment values (..., N, 2 M) -> cells (..., N, M)."""
        first = (y @ self.right_t).reshape(*y.shape[:-2], self.n_rows * 2 * self.rank, self.n_cols)
        return self.left_t @ first

    def step(self, x: torch.Tensor, loads: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The stepped maps (B, N, M) and the model loads of ``x`` (B, N + M).

        Non-negative maps give non-negative stress up to rounding: the factors' float32 rounding
        leaves stresses of order -1e-7 kPa where no load reaches, which move a gain by 1e-9 and
        are not clamped (a clamp would switch the gradient off wherever rounding flips the sign
        of a zero stress; the dense form's gradient has no such jumps)."""
        stress = self.stress(x)
        if self.exponent == 1.0:
            shifted = stress + self.p0
            gain = stress / shifted  # law_gain at n = 1, its denominator kept for the slope
        else:
            gain = law_gain(stress, self.p0, self.exponent)
        model = gain.reshape(-1, 2 * self.n_rows * self.n_cols) @ self.sums
        # the measured and the model loads spread over their segments, (2, B, N, 2 M)
        spread = (torch.cat([loads, model], dim=0) @ self.expand).reshape(2, -1, self.n_rows, 2 * self.n_cols)
        if self.exponent == 1.0:
            # df/ds = n / p0 (1 - f)^2 = p0 / (s + p0)^2: constants cancel in the ratio; p0^2 is in
            # ``expand``
            weighted = spread / (shifted * shifted)
        else:  # (1 - f)^((n + 1) / n) = (1 + s / p0)^-(n + 1)
            weighted = spread * torch.pow(1.0 + stress / self.p0, -(self.exponent + 1.0))
        numerator, denominator = (self.back(weighted) + RATIO_EPS).chunk(2, dim=0)  # J^T L, J^T L_model
        ratio = (numerator / denominator).clamp(max=RATIO_CAP)
        return x * ratio.reshape(x.shape), model

    def forward(self, maps: torch.Tensor, loads: torch.Tensor) -> torch.Tensor:
        x = maps.reshape(maps.shape[0], self.n_rows, self.n_cols)
        return self.step(x, loads)[0].reshape(maps.shape)
