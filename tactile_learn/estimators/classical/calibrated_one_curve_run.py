"""The calibrated fit's batch-1 path: one curve checked and scored in the fewest numpy calls.

At batch 1 the factored products (:mod:`.calibrated_one_curve`) are ~15 us of arithmetic, bound by
reading their ~0.9 MB of factors, and each numpy call around them costs ~0.6-1 us whatever its size
(a strided or multi-axis one ~2 us): the full input check was a dozen calls, the scoring twenty.
:class:`OneCurveRun` does the same work with its layout prepared once:

- **a shift, not a centring**: the first stage's columns are centred themselves (``U - 1 1^T U /
  N``), so ``U^T (y - c)`` is ``U^T (y - mean)`` for any ``c``; the curve is shifted by its first
  value (one pass less than its mean) and ``|y - mean|^2 = |y - c|^2 - (sum of y - c)^2 / N``,
  the sum read from a column of ones in the same product. As ``c`` is a value of the curve,
  ``N (mean - c)^2 <= N |y - mean|^2``: the subtraction cancels at most a factor ``N + 1``, the
  relative rounding a length-``N`` dot product has itself;
- **the check from numbers already there**: every value lies within ``|y - m 1|`` of any ``m``, so
  a float32 curve of the scene's shape whose mean +- ``|y - mean|`` lies inside the full check's
  bounds (:meth:`~tactile_learn.validation.common.InputCheck.bounds`: the ADC's open range) is
  valid with no pass of its own (~70 % of touches); the others are checked by their smallest and
  largest values; a curve that fails (NaN, inf, out of range), another shape, dtype or type gives
  ``None``, and the caller takes the full check: its clear error, or the answer;
- **packed stages**: the first stage holds only each start's ``r_s`` columns (no padding to ``R``),
  and the second stage's blocks ``C_s`` (``r_s`` rows) are overlapping windows of ``R`` rows of
  one buffer (:func:`overlapping_windows`: a window's rows past its block are a neighbour's,
  multiplied by exact zeros); one ``take`` gathers each window's coordinates (zeros from a zero
  column). The seed scene reads 0.92 MB instead of 1.05 MB (measured ~1 us a curve: the working
  set is near the core's L2);
- **one complex modulus per design**: with ``L = 2`` (the seed scenes) each start's coordinate
  matrix keeps the two columns of a design side by side, read as one complex column, so the norm
  of a design's projection is the modulus of one complex number: one ``abs`` over a contiguous
  array instead of a square and an add of strided halves; the maxima over starts and within a
  class are taken on the moduli (the square is monotone) (other ``L``: squares summed, as the
  batch does);
- **scores in place, the tail on Python floats**: the coordinate matrices are scaled by
  ``sqrt(1 / (2 sigma^2))``, so a squared norm is a score; the class scores are then
  ``-(|y|^2 - best)`` and the softmax needs only ``best - top`` for ``K + 1`` numbers (fewer
  calls in Python than numpy's), with a clamp only where rounding lifts a projection above
  ``|y|^2`` (where the batch clamps a residual at 0).

The numbers are the batch path's to rounding: the same factors, shifted, scaled by one constant
and summed in another order (tests: probabilities within 1e-7 of the batch's and the same labels
on simulated, recorded and extreme curves; measured: 7e-12 on 400 bench curves, 7e-19 on the 90
robot recordings).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tactile_learn.estimators.classical.calibrated_one_curve import StartFactoredBases

__all__ = ["OneCurveRun", "overlapping_windows"]

_F32 = np.dtype(np.float32)
_F64 = np.float64
_C128 = np.complex128
_max_of = np.maximum.reduce
_min_of = np.minimum.reduce
_sum_of = np.add.reduce
_matmul = np.matmul
_abs = np.abs
_exp = math.exp


@dataclass(frozen=True, eq=False)
class OneCurveRun:
    """Check and score one curve (module docstring). ``run(x)``: the probabilities ``(1, K + 1)``
    float32 of a plain valid curve ``x`` ``(1, *shape)``, else ``None``;
    :meth:`probabilities`: those of a curve already checked."""

    first: np.ndarray  # (N, P): the first stage packed: every start's r_s columns, the lines', ones, zeros
    coordinates: np.ndarray  # (S, 1, R) int: where start s's i-th coordinate is in y @ first (a zero past r_s)
    second: np.ndarray  # (S, R, L M) scaled, overlapping windows; with pairs: design m's at 2 m, 2 m + 1
    class_start: np.ndarray  # (K,) where each class's templates begin
    batch_shape: tuple[int, ...]  # (1, *shape) of a curve
    bounds: tuple[float, float, bool] | None  # (low, high, low strict) of the full check, if exact
    n_values: int  # N
    n_templates: int  # M
    n_columns: int  # L
    centred: bool
    pairs: bool  # L == 2: coordinates read as complex numbers
    lines: slice  # the lines' coordinates in y @ first
    ones_at: int  # where y's sum is in y @ first (centred)
    scale: float  # 1 / (2 sigma^2): a squared norm's score (unscaled: the lines' part)
    none_bonus: float

    @classmethod
    def build(
        cls, factors: StartFactoredBases, shape: tuple[int, ...], bounds: tuple[float, float, bool] | None
    ) -> OneCurveRun:
        """From the factored bases of the calibrated fit, the shape of one curve and the bounds of
        the full input check (``None``: the check maps its input, every curve takes it)."""
        second = factors.second
        n_starts, width, n_cols_m = second.shape
        n_cols = factors.n_columns
        m = n_cols_m // n_cols
        scale = -factors.scale
        scaled = second * math.sqrt(scale)
        pairs = n_cols == 2
        if pairs:  # column l M + m -> 2 m + l: a design's two coordinates as one complex number
            scaled = np.ascontiguousarray(scaled.reshape(n_starts, width, 2, m).transpose(0, 1, 3, 2))
            scaled = scaled.reshape(n_starts, width, n_cols_m)
        # the first stage without the columns that only pad each start to R (a sixth of its bytes),
        # then the lines' (nonzero) columns, the ones vector (y's sum) and a zero column (padding)
        used = np.abs(factors.first).max(axis=0) > 0
        ranks = used[: n_starts * width].reshape(n_starts, width).sum(axis=1)
        lines = factors.first[:, n_starts * width :][:, used[n_starts * width :]]
        n = len(factors.first)
        kept = factors.first[:, : n_starts * width][:, used[: n_starts * width]]
        packed = np.concatenate([kept, lines, np.ones((n, 1)), np.zeros((n, 1))], axis=1)
        if factors.centred:  # U' = U - 1 (1^T U) / N: U'^T y = U^T (y - mean) for any y (a shifted curve)
            packed[:, :-2] -= packed[:, :-2].mean(axis=0)
        windows, placed = overlapping_windows([scaled[s, :r] for s, r in enumerate(ranks)], width)
        # each window's coordinates: start s's where its rows were placed, zeros elsewhere (the
        # rows there are other starts': multiplied by exact zeros)
        coordinates = np.full((n_starts, 1, width), packed.shape[1] - 1)
        first_column = np.r_[0, np.cumsum(ranks)]
        for window, (s, offset) in enumerate(placed):
            coordinates[window, 0, offset : offset + ranks[s]] = first_column[s] + np.arange(ranks[s])
        return cls(
            first=np.ascontiguousarray(packed),
            coordinates=coordinates,
            second=windows,
            class_start=factors.class_start,
            batch_shape=(1, *shape),
            bounds=bounds,
            n_values=n,
            n_templates=m,
            n_columns=n_cols,
            centred=factors.centred,
            pairs=pairs,
            lines=slice(kept.shape[1], kept.shape[1] + lines.shape[1]),
            ones_at=packed.shape[1] - 2,
            scale=scale,
            none_bonus=factors.none_bonus,
        )

    def __call__(self, x: object) -> np.ndarray | None:
        if type(x) is not np.ndarray or x.shape != self.batch_shape or x.dtype != _F32 or self.bounds is None:
            return None
        return self._scored(x, True)

    def _in_range(self, x: np.ndarray, lo: float, hi: float) -> bool:
        """Whether the values of ``x``, known to lie from ``lo`` to ``hi`` (NaN: unknown), pass the
        full check's range: its smallest or largest value is read only where ``lo`` or ``hi`` does
        not decide (NaN in ``x`` passes no comparison)."""
        low, high, strict = self.bounds  # type: ignore[misc]
        if not hi < high and not float(_max_of(x, axis=None)) < high:
            return False
        if strict:
            return lo > low or float(_min_of(x, axis=None)) > low
        return lo >= low or float(_min_of(x, axis=None)) >= low

    def probabilities(self, x: np.ndarray) -> np.ndarray:
        """The probabilities ``(1, K + 1)`` float32 of one checked curve ``x`` ``(1, *shape)``."""
        out = self._scored(x, False)
        assert out is not None  # (unchecked: always scored)
        return out

    def _scored(self, x: np.ndarray, check: bool) -> np.ndarray | None:
        y = x.reshape(-1).astype(_F64)  # a copy of its own: shifted in place
        if self.centred:
            # shifted by its first value, not centred (one pass less): the first stage's columns
            # are centred themselves, and |y - mean|^2 = |y - c|^2 - N (mean - c)^2 cancels at most
            # a factor N + 1 (c is a value of y: |mean - c| <= |y - mean|), the rounding of a
            # length-N dot product
            shift = float(y[0])
            if check and not math.isfinite(shift):  # NaN or inf: the full check's error
                return None
            y -= shift
            squares = float(y.dot(y))  # (ndarray.dot: less overhead than @ at this size)
            if check and not math.isfinite(squares):  # NaN or inf (before a product warns of it)
                return None
            z = y.dot(self.first)
            total = float(z[self.ones_at])
            yy = max(squares - total * total / self.n_values, 0.0)
            if check:
                # every value lies within |y - m 1| of any m: a curve whose mean +- |y - mean| lies
                # inside the bounds is valid with no pass of its own (~70 % of touches; the others
                # read their extreme on the side in doubt); the factor covers the rounding of
                # |y - mean|^2, the absolute term the sums'
                mean = shift + total / self.n_values
                reach = math.sqrt(yy) * (1.0 + 1e-9) + 1e-12 * abs(mean)
                if not self._in_range(x, mean - reach, mean + reach):
                    return None  # out of range: the full check's error
        else:
            yy = float(y.dot(y))
            if check and not self._in_range(x, math.nan, math.nan):
                return None  # out of range, NaN or inf: the full check's error
        if not self.centred:
            z = y.dot(self.first)
        second = self.second
        proj = _matmul(z.take(self.coordinates), second)  # (S, 1, L M): scaled coordinates
        n_starts = second.shape[0]
        m = self.n_templates
        if self.pairs:
            by_design = _abs(proj.view(_C128)).reshape(n_starts, m)  # norms
        else:
            proj *= proj
            flat = proj.reshape(n_starts, -1)
            by_design = flat[:, :m]
            for column in range(1, self.n_columns):
                by_design = by_design + flat[:, column * m : (column + 1) * m]
        # each class's best over its templates and starts: norms (pairs) or squared norms
        values = np.maximum.reduceat(_max_of(by_design, axis=0), self.class_start).tolist()
        # the rest on K + 2 Python floats (fewer calls than numpy's on arrays this short)
        squared = not self.pairs
        top = max(values) if squared else max(values) ** 2
        scale = self.scale
        yy *= scale
        if top > yy:  # a projection above |y|^2 by rounding: the batch's residual clamped at 0
            values = [min(v if squared else v * v, yy) for v in values]
            squared, top = True, yy
        # the lines' score (+ bonus) less -|y|^2, as the classes'
        none = min(scale * sum([v * v for v in z[self.lines].tolist()]), yy) + self.none_bonus
        top = max(top, none)
        e = [_exp(v - top) for v in values] if squared else [_exp(v * v - top) for v in values]
        e.append(_exp(none - top))
        inv_total = 1.0 / sum(e)
        return np.array([[v * inv_total for v in e]], dtype=_F32)


def overlapping_windows(blocks: list[np.ndarray], width: int) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """The blocks ``(r_s, C)`` (``r_s <= width``) as a read-only stack of windows ``(S, width, C)``
    of one buffer, window ``k`` its rows ``k D`` to ``k D + width``: each window holds one block's
    rows whole (at an offset), the rest of it the neighbours' rows. With ``D`` below ``width`` the
    stack reads fewer bytes than blocks zero-padded to ``width`` (the batched product of a window
    with coordinates that are zero outside its block's rows is the block's product). Blocks are
    placed largest, smallest, next largest, ... (so that short ones make room for long ones); ``D``
    is the smallest that fits. Also, per window, (block, offset of its rows in the window)."""
    n, columns = len(blocks), blocks[0].shape[1]
    by_size = sorted(range(n), key=lambda b: -len(blocks[b]))
    order = [by_size[i // 2] if i % 2 == 0 else by_size[n - 1 - i // 2] for i in range(n)]
    for step in range(-(-sum(len(b) for b in blocks) // n), width + 1):
        starts, end = [], 0
        for window, b in enumerate(order):
            start = max(end, window * step)
            if start + len(blocks[b]) > window * step + width:
                break
            starts.append(start)
            end = start + len(blocks[b])
        else:
            break
    buffer = np.zeros(((n - 1) * step + width, columns))
    for b, start in zip(order, starts, strict=True):
        buffer[start : start + len(blocks[b])] = blocks[b]
    row = buffer.strides[0]
    windows = np.lib.stride_tricks.as_strided(
        buffer, shape=(n, width, columns), strides=(step * row, row, buffer.strides[1]), writeable=False
    )
    return windows, [(b, start - window * step) for window, (b, start) in enumerate(zip(order, starts, strict=True))]
