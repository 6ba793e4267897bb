"""The calibrated fit's bases of every (contact start, template) design, factored per start.

At batch 1 the calibrated fit's cost is reading its bases: ``|Q^T y|^2`` of one curve against every
design is a matrix-vector product over an ``(N, G L)`` matrix (3.5 MB on the seed scene), which no
cache holds and which no arithmetic hides (a batch reuses each byte for every curve). Those bases
are far from independent: at one contact start, every template's curves are the same physics with
another effusivity, conductance or build-up, so the ``M L`` columns of that start's ``M``
templates span a space of small dimension ``r_s`` (the seed scene: ``r_s <= 28`` of 216 columns,
125 samples). With ``U_s`` an orthonormal basis of that span (``N x r_s``) and
``C_s = U_s^T Q_s``, each design's projections are

    Q_{s,m}^T y = C_{s,m}^T (U_s^T y),

exactly where ``Q_s``'s columns lie in ``span U_s``. So a curve is read once by every start's
``U_s`` (one product, ``N x sum r_s``), and each start's small coordinates by its ``C_s`` (one
batched product): a third of the bytes. ``r_s`` is the smallest rank that leaves no column of
``Q_s`` more than ``4 N eps`` outside ``span U_s``: the error this adds to a projection is at most
``4 N eps |y|``, four times the rounding a length-``N`` dot product may make itself (the dense
product's own worst case), and the residual sums of squares agree with the dense path's to its
rounding (tests; the batch's probabilities of 400 bench curves and of the 90 robot recordings
are those at ``N eps`` bit for bit). (At ``N eps`` the seed scene's widest start needed 29 columns, at ``4 N eps``
24: its last few singular values are the dense bases' own rounding, and batch 1 reads 17 % fewer
bytes, which keeps its working set near the core's L2.)

The batch path (:meth:`StartFactoredBases.scores`) and the single-curve path
(:mod:`.calibrated_one_curve_run`) read these factors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["StartFactoredBases"]


@dataclass(frozen=True)
class StartFactoredBases:
    """The calibrated fit's per-curve scores from bases factored per contact start (see the module
    docstring). Arrays, all float64:

    - ``first``: ``(N, S R + L)``: every start's ``U_s`` side by side (``R = max r_s``, zero columns
      beyond ``r_s``), then the no-contact lines' own basis (``L`` columns);
    - ``second``: ``(S, R, L M)``: each start's ``C_s``, column ``l M + m`` the ``l``-th basis
      column of template ``m`` (templates sorted by class), zero rows beyond ``r_s``;
    - ``class_start``: where each class's templates begin (K,).
    """

    first: np.ndarray
    second: np.ndarray
    class_start: np.ndarray
    n_columns: int
    centred: bool
    scale: float  # -1 / (2 sigma^2): a residual sum of squares' score
    none_bonus: float

    @classmethod
    def build(
        cls,
        q: np.ndarray,
        n_columns: int,
        centred: bool,
        design_start: np.ndarray,
        design_template: np.ndarray,
        template_class: np.ndarray,
        sigma: float,
        none_bonus: float,
    ) -> StartFactoredBases:
        """From the dense bases ``q`` (N, (G + 1) L) of the calibrated fit (``G`` designs, then the
        lines), each design's contact start and template index (G,), and each template's class."""
        n, n_cols = q.shape[0], n_columns
        n_starts, n_templates = int(design_start.max()) + 1, len(template_class)
        if len(design_start) != n_starts * n_templates or q.shape[1] != (len(design_start) + 1) * n_cols:
            raise ValueError("calibrated bases: every (start, template) needs exactly one design")
        by_class = np.argsort(template_class, kind="stable")
        rank_of = np.empty(n_templates, dtype=np.int64)
        rank_of[by_class] = np.arange(n_templates)
        # (S, N, L, M): design (start s, template m)'s l-th column at [s, :, l, rank_of[m]]
        grid = np.empty((n_starts, n, n_cols, n_templates))
        designs = q[:, : len(design_start) * n_cols].reshape(n, len(design_start), n_cols)
        grid[design_start, :, :, rank_of[design_template]] = designs.transpose(1, 0, 2)
        tol = 4 * n * np.finfo(np.float64).eps  # per column of unit (or zero) norm: see the module docstring
        us, cs = [], []
        for start in grid:
            u, sv, vt = np.linalg.svd(start.reshape(n, n_cols * n_templates), full_matrices=False)
            # each column's distance to the span of the first r singular vectors, for every r
            weighted = (sv[:, None] * vt) ** 2
            outside = np.sqrt(np.maximum(weighted[::-1].cumsum(axis=0)[::-1], 0.0)).max(axis=1)
            rank = int(np.argmax(np.r_[outside, 0.0] <= tol))
            us.append(u[:, :rank])
            cs.append(sv[:rank, None] * vt[:rank])
        width = max(1, max(u.shape[1] for u in us))
        first = np.zeros((n, n_starts * width + n_cols))
        second = np.zeros((n_starts, width, n_cols * n_templates))
        for s, (u, c) in enumerate(zip(us, cs, strict=True)):
            first[:, s * width : s * width + u.shape[1]] = u
            second[s, : u.shape[1]] = c
        first[:, n_starts * width :] = q[:, -n_cols:]
        sorted_class = template_class[by_class]
        class_start = np.flatnonzero(np.r_[True, sorted_class[1:] != sorted_class[:-1]])
        return cls(first, second, class_start, n_cols, centred, -1.0 / (2.0 * sigma**2), none_bonus)

    def scores(self, y: np.ndarray) -> np.ndarray:
        """The class scores ``-RSS / (2 sigma^2)`` (b, K + 1) of the curves ``y`` (b, C W) float64, a
        copy of their own (centred in place): a batch's product with every start's ``U_s``, then one
        batched product per start with its ``C_s`` (a batch reads the bases once for all its curves;
        the factored products are ~2.5 times fewer multiply-adds than the dense bases')."""
        if self.centred:
            y -= y.mean(axis=1, keepdims=True)
        second = self.second
        n_starts, width, n_cols = second.shape[0], second.shape[1], self.n_columns
        b, m = len(y), second.shape[2] // n_cols
        z = y @ self.first
        lines = z[:, n_starts * width :]
        proj = np.matmul(z[:, : n_starts * width].reshape(b, n_starts, width).transpose(1, 0, 2), second)
        proj *= proj  # (S, b, L M)
        by_design = proj[..., :m]
        for column in range(1, n_cols):  # a sum over a short axis: adds of slices beat a reduce
            by_design = by_design + proj[..., column * m : (column + 1) * m]
        yy = np.einsum("bi,bi->b", y, y)[:, None]
        scores = np.empty((b, len(self.class_start) + 1))
        scores[:, :-1] = np.maximum.reduceat(by_design.max(axis=0), self.class_start, axis=1)
        scores[:, -1] = np.einsum("bi,bi->b", lines, lines)
        # residual sums of squares |y|^2 - |Q^T y|^2, clamped at 0 (which rounding can go below)
        np.minimum(scores, yy, out=scores)
        np.subtract(yy, scores, out=scores)
        scores *= self.scale
        scores[:, -1] += self.none_bonus
        return scores
