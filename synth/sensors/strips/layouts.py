"""Strip layouts: which strips lie over the array and how each is read (``strips.geometry.layout``,
:class:`StripGeometry`).

Every layout is described the same way: *layers* of strips, each layer at its own depth under the
cover, and *channels* (one reading each) that are weighted sums of the piezoresistive conductance
share ``f`` of the segments of one layer. A segment is the ``pitch``-long piece of a strip over one
intersection cell ``(i, j)``, so a layer's segments form an ``(N, M)`` grid:

- ``row`` layer (depth ``cover_mm``): row strip ``i`` owns the segments ``(i, :)``;
- ``col`` layer (``cover_mm + strip_thickness_mm``): column strip ``j`` owns ``(:, j)``;
- ``diag+45`` / ``diag-45`` layers (one further ``strip_thickness_mm`` each): diagonal strip ``d``
  owns the cells with ``j - i = d - (N - 1)`` (+45 degrees: x and y grow together) or
  ``i + j = d`` (-45 degrees), ``N + M - 1`` strips per layer. A diagonal segment sees the mean
  stress over its whole cell at its depth (a simplification: the real strip covers a diagonal band
  of the cell). A diagonal strip shorter than the longest is made up to the longest one's length
  by a fixed series resistor, so a short corner strip does not saturate its readout.

Readouts (``StripLayout.linear`` tells which per channel):

- *series* (every layout but ``two_ended``): the strip in a divider, the reading a function of
  ``share`` = the sum of ``f`` over the segments it reads divided by its full strip's segment count
  (``StripLayout.segments``) - for a whole row or column strip exactly the orthogonal array's
  readout; a tapped strip carries the divider's current and each section's voltage drop is read
  against the whole strip's unloaded resistance, so its sections' loads add up to the strip's;
- *current division* (``two_ended``): a common electrode under the strip is driven, pressure opens a
  conductance ``~ f`` into the strip at each segment, and both ends are held at virtual ground by
  transimpedance amplifiers. A uniform resistive strip splits a segment's current ``(1 - t)`` to
  the near end and ``t`` to the far end (``t``: the segment's position along the strip, 0 to 1), so
  the near + far readings give the strip's load and ``far / (near + far)`` the load's centroid
  along it. Both ends read ``offset_v + amplifier_gain * supply_v / 4 * share`` (``share``: the
  end's weighted sum of ``f`` over the strip's segment count), the same small-load slope as the
  series readout.

Readings order (``readings`` (B, C)), per layout:

- ``orthogonal`` (C = N + M): rows ``0..N-1``, then columns ``0..M-1``;
- ``diagonal`` (C = N + M + k (N + M - 1)): rows, columns, then the +45 strips (``diagonals`` =
  ``"+45"`` or ``"both"``) ordered by ``j - i`` ascending, then the -45 strips (``"-45"`` or
  ``"both"``) ordered by ``i + j`` ascending;
- ``two_ended`` (C = 2 (N + M)): the rows' near ends (x = 0), the rows' far ends, the columns' near
  ends (y = 0), the columns' far ends;
- ``taps`` (C = T (N + M), T = ``taps``): row ``i``'s sections ``0..T-1`` along x at ``i T + k``,
  then column ``j``'s sections along y at ``N T + j T + k``. The taps sit at the segment boundaries
  nearest to ``k L / T`` (``L`` segments), symmetric about the strip's middle.

Gains (``latent_strip_gain``) are per physical strip: rows, columns, then diagonals in the order above.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np

from synth.config import param
from synth.errors import ConfigError

__all__ = ["LAYOUTS", "StripGeometry", "StripLayout"]

LAYOUTS = ("orthogonal", "diagonal", "two_ended", "taps")


@dataclass(frozen=True)
class StripGeometry:
    """Row strips run along x and are stacked along y; column strips run along y. Intersection
    (i, j) is the ``pitch x pitch`` cell centred where row ``i`` crosses column ``j``."""

    n_rows: int = param(16, lo=1, hi=128, doc="row strips (N)")
    n_cols: int = param(16, lo=1, hi=128, doc="column strips (M)")
    pitch_mm: float = param(2.5, lo=0.1, hi=50.0, unit="mm", doc="centre-to-centre strip spacing")
    strip_width_mm: float = param(2.0, lo=0.01, hi=50.0, unit="mm", doc="conductive width of a strip")
    samples_per_pitch: int = param(4, lo=4, hi=32, doc="fine-lattice samples per pitch (pressure field)")
    layout: Literal["orthogonal", "diagonal", "two_ended", "taps"] = param(
        "orthogonal",
        omit_default=True,
        doc="strips and readout (synth.sensors.strips.layouts): the orthogonal pair; + diagonal strips; "
        "rows and columns read at both ends; rows and columns read between taps",
    )
    diagonals: Literal["+45", "-45", "both"] = param(
        "+45", omit_default=True, doc="diagonal layers of layout 'diagonal', each one strip thickness deeper"
    )
    taps: int = param(2, lo=2, hi=64, omit_default=True, doc="sections (readings) per strip of layout 'taps'")

    def __post_init__(self) -> None:
        if self.layout == "taps" and self.taps > min(self.n_rows, self.n_cols):
            raise ConfigError(
                f"geometry.taps: {self.taps} sections per strip, but a strip has only "
                f"{min(self.n_rows, self.n_cols)} segments"
            )
        if self.strip_width_mm > self.pitch_mm:
            raise ConfigError(
                f"geometry.strip_width_mm: {self.strip_width_mm} mm is wider than the pitch ({self.pitch_mm} mm)"
            )


@dataclass(frozen=True)
class _Group:
    name: str
    start: int
    stop: int


class StripLayout:
    """Layers, channels and their weights for one geometry (see the module docstring)."""

    def __init__(self, geometry: StripGeometry) -> None:
        n, m = geometry.n_rows, geometry.n_cols
        self.name = geometry.layout
        self.n_rows, self.n_cols = n, m
        layers = ["row", "col"]
        if self.name == "diagonal":
            layers += [f"diag{a}" for a in ("+45", "-45") if geometry.diagonals in (a, "both")]
        self.layers = tuple(layers)
        i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
        # physical strip of every segment, per layer (which gain it carries)
        strip = [i, n + j]
        first = n + m
        for layer in self.layers[2:]:
            strip.append(first + (j - i + n - 1 if layer == "diag+45" else i + j))
            first += n + m - 1
        self.n_strips = first
        self.segment_strip = np.stack(strip)  # (L, N, M)

        weights: list[np.ndarray] = []
        linear: list[bool] = []
        groups: list[_Group] = []

        def add(name: str, block: np.ndarray, is_linear: bool = False) -> None:
            groups.append(_Group(name, sum(len(w) for w in weights), sum(len(w) for w in weights) + len(block)))
            weights.append(block)
            linear.extend([is_linear] * len(block))

        def strips_of(layer: int, count: int, offset: int) -> np.ndarray:
            """(count, L, N, M) indicators of whole strips of one layer."""
            block = np.zeros((count, len(self.layers), n, m))
            block[self.segment_strip[layer] - offset, layer, i, j] = 1.0
            return block

        rows, cols = strips_of(0, n, 0), strips_of(1, m, n)
        if self.name == "two_ended":
            # position of each segment's centre along its strip, 0 at the near end, 1 at the far end
            t_row = (j + 0.5) / m
            t_col = (i + 0.5) / n
            add("row_near", rows * (1.0 - t_row), True)
            add("row_far", rows * t_row, True)
            add("col_near", cols * (1.0 - t_col), True)
            add("col_far", cols * t_col, True)
        elif self.name == "taps":
            taps = geometry.taps
            add("row_sections", _sections(rows, taps, along=j, length=m))
            add("col_sections", _sections(cols, taps, along=i, length=n))
        else:
            add("rows", rows)
            add("cols", cols)
            offset = n + m
            for index, layer in enumerate(self.layers[2:], start=2):
                add(layer, strips_of(index, n + m - 1, offset))
                offset += n + m - 1
        self.weights = np.concatenate(weights)  # (C, L, N, M)
        self.linear = np.array(linear)
        self.groups = tuple(groups)
        self.n_channels = len(self.weights)
        #: physical strip of each channel
        whole = self.weights.reshape(self.n_channels, len(self.layers), -1) > 0
        layer_of = np.argmax(whole.any(axis=2), axis=1)
        first_cell = np.argmax(whole[np.arange(self.n_channels), layer_of], axis=1)
        self.channel_strip = self.segment_strip.reshape(len(self.layers), -1)[layer_of, first_cell]
        #: segments of each channel's full strip: the denominator of its share (a row strip's M, a
        #: column's N, a diagonal's min(N, M), whatever part of the strip the channel reads)
        full = np.concatenate([np.full(n, m), np.full(m, n), np.full(self.n_strips - n - m, min(n, m))])
        self.segments = full[self.channel_strip].astype(np.float64)

    @property
    def orthogonal(self) -> bool:
        return self.name == "orthogonal"

    def group(self, name: str) -> slice:
        for g in self.groups:
            if g.name == name:
                return slice(g.start, g.stop)
        raise KeyError(name)

    @cached_property
    def flat_weights(self) -> np.ndarray:
        """(C, L*N*M): channel load = ``flat_weights @ f.ravel()``."""
        return self.weights.reshape(self.n_channels, -1)

    @cached_property
    def strip_totals(self) -> tuple[np.ndarray, np.ndarray]:
        """(C, N) and (C, M): summing channel loads with these gives each row and column strip's load."""
        to_rows = np.zeros((self.n_channels, self.n_rows))
        to_cols = np.zeros((self.n_channels, self.n_cols))
        for c, s in enumerate(self.channel_strip):
            if s < self.n_rows:
                to_rows[c, s] = 1.0
            elif s < self.n_rows + self.n_cols:
                to_cols[c, s - self.n_rows] = 1.0
        return to_rows, to_cols

    def row_col_loads(self, loads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row and column strip loads (B, N), (B, M) from channel loads (B, C)."""
        to_rows, to_cols = self.strip_totals
        return loads @ to_rows, loads @ to_cols

    def flip_permutation(self, flip_y: bool, flip_x: bool) -> np.ndarray | None:
        """Channel order of the mirrored array (mirror the map's rows and/or columns), or ``None``
        where the mirror is no symmetry of the layout (a +45 layer alone becomes a -45 one)."""
        # rounded: a two-ended strip's mirrored (1 - t) equals t only to rounding
        weights = np.round(self.weights, 9) + 0.0  # + 0.0: no -0.0 keys
        w = weights[:, :, :: -1 if flip_y else 1, :: -1 if flip_x else 1]
        index = {weights[c].tobytes(): c for c in range(self.n_channels)}
        perm = [index.get(np.ascontiguousarray(w[c]).tobytes()) for c in range(self.n_channels)]
        if any(p is None for p in perm):
            return None
        return np.array(perm, dtype=np.int64)


def _sections(strips: np.ndarray, taps: int, along: np.ndarray, length: int) -> np.ndarray:
    """Split every strip of ``strips`` (S, L, N, M) into ``taps`` sections along ``along``."""
    # taps at the segment boundaries nearest to even spacing, symmetric about the strip's middle
    # (a mirrored array is then the same array: the training augmentation relies on it)
    edges = np.floor(np.arange(taps + 1) * length / taps + 0.5).astype(int)
    edges[taps - np.arange(taps // 2 + 1)] = length - edges[: taps // 2 + 1]
    section = np.searchsorted(edges, along, side="right") - 1  # (N, M)
    out = np.zeros((len(strips), taps, *strips.shape[1:]))
    for k in range(taps):
        out[:, k] = strips * (section == k)
    return out.reshape(-1, *strips.shape[1:])
