"""The strip array's mechanics: surface pressure on the fine lattice -> mean stress on every strip
segment of every layer (Boussinesq's rectangle kernel at each layer's depth, separable by SVD; see
:mod:`synth.sensors.strips.physics` for the whole chain)."""

from __future__ import annotations

import numpy as np

from synth.errors import InputError
from synth.mechanics import patch_operator, separable_kernel
from synth.sensors.strips.config import StripsConfig
from synth.sensors.strips.layouts import StripLayout
from synth.stimuli import Windows

__all__ = ["StripArray"]


def _band_weights(n: int, cells: int, h: float, pitch: float, width: float) -> np.ndarray:
    """(n, cells): share of each lattice cell inside strip ``i``'s band, normalised to average."""
    lo = np.arange(n) * pitch + (pitch - width) / 2
    edges = np.arange(cells + 1) * h
    overlap = np.clip(
        np.minimum(edges[1:][None, :], (lo + width)[:, None]) - np.maximum(edges[:-1][None, :], lo[:, None]),
        0,
        None,
    )
    return overlap / width


def _segment_weights(n: int, per: int) -> np.ndarray:
    """(n, n*per): average over the ``per`` lattice cells of each pitch-long segment."""
    return np.kron(np.eye(n), np.full((1, per), 1.0 / per))


class StripArray:
    """Geometry and mechanics: surface pressure -> mean stress on every strip segment.

    Pressure may sit on a padded lattice reaching ``pad`` cells beyond the array on every side
    (contacts near or past the border load the strips through the cover too).
    """

    def __init__(self, config: StripsConfig, pad: int = 0) -> None:
        g, layers = config.geometry, config.layers
        self.config = config
        self.n_rows, self.n_cols, self.s = g.n_rows, g.n_cols, g.samples_per_pitch
        self.h = g.pitch_mm / g.samples_per_pitch
        self.field_shape = (g.n_rows * self.s, g.n_cols * self.s)
        self.pad = pad
        ny, nx = self.field_shape
        pos_y = np.arange(-pad, ny + pad)
        pos_x = np.arange(-pad, nx + pad)
        half = max(ny, nx) + pad
        row_band = _band_weights(g.n_rows, ny, self.h, g.pitch_mm, g.strip_width_mm)
        col_band = _band_weights(g.n_cols, nx, self.h, g.pitch_mm, g.strip_width_mm)
        seg_x = _segment_weights(g.n_cols, self.s)
        seg_y = _segment_weights(g.n_rows, self.s)
        self.depth_row_mm = layers.cover_mm
        self.depth_col_mm = layers.cover_mm + layers.strip_thickness_mm
        k_row = separable_kernel(self.h, self.depth_row_mm, half, layers.kernel_rank_tol)
        k_col = separable_kernel(self.h, self.depth_col_mm, half, layers.kernel_rank_tol)
        self.kernel_rel_error = max(k_row.rel_error, k_col.rel_error)
        f32 = np.float32
        # row layer: average across row i's band (y) and along segment j (x)
        self.row_y = np.stack([patch_operator(row_band, r, pos_y, half) for r in k_row.rows]).astype(f32)
        self.row_x = np.stack([patch_operator(seg_x, c, pos_x, half) for c in k_row.cols]).astype(f32)
        # column layer: along segment i (y) and across column j's band (x)
        self.col_y = np.stack([patch_operator(seg_y, r, pos_y, half) for r in k_col.rows]).astype(f32)
        self.col_x = np.stack([patch_operator(col_band, c, pos_x, half) for c in k_col.cols]).astype(f32)
        # diagonal layers (layout 'diagonal'), each one strip thickness below the one above it: a
        # diagonal segment sees the mean stress over its whole cell at its depth (synth.sensors.strips.layouts)
        self.layout = StripLayout(g)
        self.depth_diag_mm = [
            layers.cover_mm + (k + 2) * layers.strip_thickness_mm for k in range(len(self.layout.layers) - 2)
        ]
        self.diag_ops: list[tuple[np.ndarray, np.ndarray]] = []
        for depth in self.depth_diag_mm:
            k_diag = separable_kernel(self.h, depth, half, layers.kernel_rank_tol)
            self.kernel_rel_error = max(self.kernel_rel_error, k_diag.rel_error)
            self.diag_ops.append(
                (
                    np.stack([patch_operator(seg_y, r, pos_y, half) for r in k_diag.rows]).astype(f32),
                    np.stack([patch_operator(seg_x, c, pos_x, half) for c in k_diag.cols]).astype(f32),
                )
            )
        self._diag_cache: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
        # ground truth: mean surface pressure over each pitch cell (zero weight outside the array)
        self.cell_y = np.zeros((g.n_rows, len(pos_y)), dtype=f32)
        self.cell_y[:, pad : pad + ny] = seg_y
        self.cell_x = np.zeros((g.n_cols, len(pos_x)), dtype=f32)
        self.cell_x[:, pad : pad + nx] = seg_x
        self._table_cache: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}

    # -- full-field path (user fields) ------------------------------------------------------------

    def _check_field(self, field: np.ndarray) -> np.ndarray:
        arr = np.asarray(field)
        if arr.ndim != 3 or arr.shape[1:] != self.field_shape:
            raise InputError(
                f"pressure field: expected shape (B, {self.field_shape[0]}, {self.field_shape[1]}), got {arr.shape}"
            )
        if not np.isfinite(arr).all():
            raise InputError("pressure field: contains NaN or inf")
        if (arr < 0).any():
            raise InputError("pressure field: negative pressure (kPa) is not a contact (the layer cannot pull)")
        return np.ascontiguousarray(arr, dtype=np.float32)

    def _inner(self, op: np.ndarray) -> np.ndarray:
        ny = op.shape[-1] - 2 * self.pad
        return op[..., self.pad : self.pad + ny]

    def segment_stress(self, field: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean stress (kPa) on every row segment and column segment, each ``(B, N, M)``, for surface
        pressure ``field`` (B, N*s, M*s) on the array's own lattice."""
        p = self._check_field(field)
        ry, rx = self._inner(self.row_y), self._inner(self.row_x)
        cy, cx = self._inner(self.col_y), self._inner(self.col_x)
        row = sum((ry[r] @ p @ rx[r].T for r in range(len(ry))), np.zeros(1, np.float32))
        col = sum((cy[r] @ p @ cx[r].T for r in range(len(cy))), np.zeros(1, np.float32))
        # the separable kernel's truncation can leave -1e-6-sized negatives far from any load
        return np.maximum(row, 0.0), np.maximum(col, 0.0)

    def diagonal_stress(self, field: np.ndarray) -> np.ndarray:
        """Mean stress (kPa) over every cell at each diagonal layer's depth, (B, D, N, M) (D = 0 for
        layouts without diagonal strips)."""
        p = self._check_field(field)
        out = np.zeros((len(p), len(self.diag_ops), self.n_rows, self.n_cols), np.float32)
        for k, (dy, dx) in enumerate(self.diag_ops):
            dy, dx = self._inner(dy), self._inner(dx)
            out[:, k] = sum((dy[r] @ p @ dx[r].T for r in range(len(dy))), np.zeros(1, np.float32))
        return np.maximum(out, 0.0)

    def cell_pressure(self, field: np.ndarray) -> np.ndarray:
        """Intersection map (B, N, M): mean surface pressure over each pitch cell."""
        p = self._check_field(field)
        return self._inner(self.cell_y) @ p @ self._inner(self.cell_x).T

    def cell_stress_operators(self) -> tuple[np.ndarray, np.ndarray]:
        """Dense ``(N*M, N*M)`` float64 matrices mapping a map of cell-constant surface pressure
        (flattened row-major) to the mean stress on every row segment and column segment."""
        up_y = np.kron(np.eye(self.n_rows), np.ones((self.s, 1)))  # lattice rows of each cell
        up_x = np.kron(np.eye(self.n_cols), np.ones((self.s, 1)))

        def dense(ops_y: np.ndarray, ops_x: np.ndarray) -> np.ndarray:
            ay = self._inner(ops_y).astype(np.float64) @ up_y  # (R, N, N)
            bx = self._inner(ops_x).astype(np.float64) @ up_x  # (R, M, M)
            # row-major vec(A X B^T) = (A kron B) vec(X)
            return np.einsum("rik,rjl->ijkl", ay, bx).reshape(self.n_rows * self.n_cols, -1)

        return dense(self.row_y, self.row_x), dense(self.col_y, self.col_x)

    def layer_cell_operators(self) -> list[np.ndarray]:
        """:meth:`cell_stress_operators` for every layer of the layout, diagonal layers last."""
        up_y = np.kron(np.eye(self.n_rows), np.ones((self.s, 1)))
        up_x = np.kron(np.eye(self.n_cols), np.ones((self.s, 1)))
        ops = list(self.cell_stress_operators())
        for dy, dx in self.diag_ops:
            ay = self._inner(dy).astype(np.float64) @ up_y
            bx = self._inner(dx).astype(np.float64) @ up_x
            ops.append(np.einsum("rik,rjl->ijkl", ay, bx).reshape(self.n_rows * self.n_cols, -1))
        return ops

    # -- windowed path (simulated contacts: work only where there is load) ---------------------

    def _tables(self, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Operators cut into every ``size``-long run of padded positions, cached per window size.

        Returns the y-table (positions, R_row + R_col + 1, N, size) holding row-layer, column-layer and
        cell-mean operators, and the x-tables (positions, R*size, M) of each layer and the cells.
        """
        cached = self._table_cache.get(size)
        if cached is None:

            def slide_y(op: np.ndarray) -> np.ndarray:
                view = np.lib.stride_tricks.sliding_window_view(op, size, axis=-1)  # (R, n, pos, size)
                return np.ascontiguousarray(view.transpose(2, 0, 1, 3))

            def slide_x(op: np.ndarray) -> np.ndarray:
                view = slide_y(op)  # (pos, R, n, size)
                pos, rank, n, _ = view.shape
                return np.ascontiguousarray(view.transpose(0, 1, 3, 2)).reshape(pos, rank * size, n)

            y = slide_y(np.concatenate([self.row_y, self.col_y, self.cell_y[None]], axis=0))
            cached = (y, slide_x(self.row_x), slide_x(self.col_x), slide_x(self.cell_x[None]))
            self._table_cache[size] = cached
        return cached

    def window_products(self, windows: Windows, stress: bool = True, cells: bool = True) -> dict[str, np.ndarray]:
        """Per-window contributions (c, N, M): ``row``/``col`` segment stress and ``cells`` means.

        Two batched matrix products per window instead of a convolution of the whole lattice.
        """
        size = windows.values.shape[-1]
        ty, trow, tcol, tcell = self._tables(size)
        iy = windows.y0 + self.pad
        ix = windows.x0 + self.pad
        if (iy < 0).any() or (iy >= len(ty)).any() or (ix < 0).any() or (ix >= len(trow)).any():
            raise ValueError("a contact window reaches beyond the padded lattice (pad too small)")
        c = len(iy)
        # the row and column layers lie at different depths: their kernels may need different ranks
        r_row, r_col = self.row_y.shape[0], self.col_y.shape[0]
        n = self.n_rows
        vals = windows.values.astype(np.float32)
        gy = ty[iy]  # (c, R_row + R_col + 1, N, size)
        first = (gy.reshape(c, -1, size) @ vals).reshape(c, r_row + r_col + 1, n, size)
        out: dict[str, np.ndarray] = {}

        def finish(part: np.ndarray, table: np.ndarray) -> np.ndarray:
            flat = np.ascontiguousarray(part.transpose(0, 2, 1, 3)).reshape(c, n, -1)
            return flat @ table[ix]

        if stress:
            out["row"] = finish(first[:, :r_row], trow)
            out["col"] = finish(first[:, r_row : r_row + r_col], tcol)
        if cells:
            out["cells"] = finish(first[:, r_row + r_col :], tcell)
        if stress and self.diag_ops:
            # separate products: the orthogonal layers' tables (and their float32 sums) stay as they were
            parts = []
            for dy, dx in self._diag_tables(size):
                rank = dy.shape[1]
                part = (dy[iy].reshape(c, -1, size) @ vals).reshape(c, rank, n, size)
                parts.append(finish(part, dx))
            out["diag"] = np.stack(parts, axis=1)
        return out

    def _diag_tables(self, size: int) -> list[tuple[np.ndarray, np.ndarray]]:
        cached = self._diag_cache.get(size)
        if cached is None:
            cached = []
            for dy, dx in self.diag_ops:
                y = np.ascontiguousarray(
                    np.lib.stride_tricks.sliding_window_view(dy, size, axis=-1).transpose(2, 0, 1, 3)
                )
                view = np.lib.stride_tricks.sliding_window_view(dx, size, axis=-1).transpose(2, 0, 1, 3)
                pos, rank, m, _ = view.shape
                x = np.ascontiguousarray(view.transpose(0, 1, 3, 2)).reshape(pos, rank * size, m)
                cached.append((y, x))
            self._diag_cache[size] = cached
        return cached
