"""Where the six discs sit and the four triangles they form (see :mod:`synth.sensors.fsr`)."""

from __future__ import annotations

import math

import numpy as np

from synth.sensors.fsr.config import LayoutConfig

__all__ = ["TRIANGLES", "barycentric", "in_triangles", "sensor_positions", "triangle_vertices"]

#: sensor indices of the four triangles (top, bottom left, bottom right, centre)
TRIANGLES: tuple[tuple[int, int, int], ...] = ((0, 3, 4), (1, 5, 3), (2, 4, 5), (3, 4, 5))


def sensor_positions(layout: LayoutConfig) -> np.ndarray:
    """(6, 2) sensor centres in mm (order S0..S5 of the module docstring), float64."""
    s = layout.side_mm
    h = 2.0 * s * math.sqrt(3.0) / 2.0  # height of the big triangle (side 2s)
    top = (0.0, 2.0 * h / 3.0)
    left = (-s, -h / 3.0)
    right = (s, -h / 3.0)
    corners = np.array([top, left, right])
    mids = np.array([(corners[0] + corners[1]) / 2, (corners[0] + corners[2]) / 2, (corners[1] + corners[2]) / 2])
    return np.concatenate([corners, mids]).astype(np.float64)


def triangle_vertices(layout: LayoutConfig) -> np.ndarray:
    """(4, 3, 2) vertices of the four triangles, in the order of :data:`TRIANGLES`."""
    pos = sensor_positions(layout)
    return pos[np.array(TRIANGLES)]


def barycentric(xy: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (..., T, 3) of points ``xy`` (..., 2) in triangles ``tri`` (T, 3, 2)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]  # (T, 2)
    v0, v1 = b - a, c - a
    det = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]  # (T,) twice the signed area: nonzero for a valid layout
    d = xy[..., None, :] - a  # (..., T, 2)
    l1 = (d[..., 0] * v1[:, 1] - d[..., 1] * v1[:, 0]) / det
    l2 = (v0[:, 0] * d[..., 1] - v0[:, 1] * d[..., 0]) / det
    return np.stack([1.0 - l1 - l2, l1, l2], axis=-1)


def in_triangles(xy: np.ndarray, layout: LayoutConfig, tol_mm: float = 0.0) -> np.ndarray:
    """Bool (...,): is each point inside (or within ``tol_mm`` of) one of the four triangles?"""
    lam = barycentric(np.asarray(xy, dtype=np.float64), triangle_vertices(layout))
    # a barycentric coordinate of -t is a distance t * height outside the opposite edge
    height = layout.side_mm * math.sqrt(3.0) / 2.0
    return np.asarray((lam.min(axis=-1) >= -tol_mm / height).any(axis=-1))
