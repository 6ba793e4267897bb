"""The deconvolution (:class:`~.capacitive.DeconvolutionEstimator`) of a single frame.

The batch path runs FISTA on a (B, H W) array: per iteration two products with the forward operator,
the Laplacian by slices (eight calls) and the prox and momentum, about twenty numpy calls. At batch
1024 the products dominate; at batch 1 each call's fixed cost does (~30 us an iteration, 3 ms a
frame). :class:`OneFrameDeconvolver` runs the same iteration on one image with the operator folded
into few, precomputed matrices, once per estimator:

- the gradient step ``y = z - step * grad`` is affine in ``z``:
  ``y = z + (Z Bx + By Z) + (z F - x) G`` with ``By = -2 step lambda Ly`` and
  ``Bx = -2 step lambda Lx`` (``Ly``, ``Lx``: the 1-D Neumann Laplacians of the image's columns
  and rows, whose Kronecker sum is the batch path's ``grad^T grad``), ``F`` the forward operator
  over the load noise and ``G = -2 step F^T``; ``z`` is added on its own, so the products carry
  only the small step (folding it into ``Bx``, ``By`` tripled the rounding error);
- ``Z Bx + By Z`` is one product of ``[Z | By]`` (H x (W + H)) with ``[Bx ; Z]`` ((W + H) x W):
  the image is kept in both blocks (one copy an iteration);
- ``z F - x`` is one product of ``[z, 1]`` with ``[F ; -x]`` (the frame's loads written into the
  last row once per frame);
- the momentum weights do not depend on the data: worked out once, as the batch path rounds them.

An iteration is then nine numpy calls on arrays of 64 to 2,048 floats (~14 us, two thirds of it the
two products with the 256 KB operator) against the batch path's ~30 us. The arithmetic is the batch
path's, grouped otherwise: results agree to float32 rounding and sit as close to a float64 run of
the batch path as the batch path itself (tests, on many frames).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["OneFrameDeconvolver", "neumann_laplacian"]


def neumann_laplacian(n: int) -> np.ndarray:
    """(n, n) ``D^T D`` of the forward difference ``D`` with free ends: the 1-D form of the batch
    path's ``_laplacian`` (degree 1 at the ends, 2 inside; -1 to each neighbour)."""
    d = np.diff(np.eye(n), axis=0)  # (n - 1, n): rows e_{i+1} - e_i
    return d.T @ d


def momentum_weights(iterations: int) -> list[np.float32]:
    """FISTA's extrapolation weights ``(t_k - 1) / t_{k+1}``, rounded to float32 as the batch path does."""
    weights, t = [], 1.0
    for _ in range(iterations):
        t_next = (1.0 + math.sqrt(1.0 + 4.0 * t * t)) / 2.0
        weights.append(np.float32((t - 1.0) / t_next))
        t = t_next
    return weights


class OneFrameDeconvolver:
    """FISTA on one image (module docstring): ``force(loads, start)`` gives the (H, W) force image.

    Holds only constants (built once, never written to): each call allocates its own buffers, so
    one deconvolver serves any number of callers and ``predict`` changes no state.
    """

    def __init__(
        self,
        forward: np.ndarray,
        noise_n: float,
        step: float,
        smoothness: float,
        image_shape: tuple[int, int],
        iterations: int,
    ) -> None:
        ny, nx = image_shape
        n_pixels, n_loads = forward.shape
        if n_pixels != ny * nx:
            raise ValueError(f"forward operator has {n_pixels} rows for an image of {ny} x {nx}")
        self.image_shape = (ny, nx)
        self.n_loads = n_loads
        self.inv_noise = np.float32(1.0 / noise_n)
        # as the batch path: the operator over the noise in float32; the folded matrices are
        # formed in float64 and rounded once
        scaled = forward.astype(np.float32) / np.float32(noise_n)
        self.forward_scaled = scaled
        self.back = np.ascontiguousarray(-2.0 * step * scaled.astype(np.float64).T, dtype=np.float32)  # G
        a = 2.0 * step * smoothness
        self.rows = (-a * neumann_laplacian(ny)).astype(np.float32)  # By
        self.cols = (-a * neumann_laplacian(nx)).astype(np.float32)  # Bx
        self.weights = momentum_weights(iterations)

    def force(self, loads: np.ndarray, start: np.ndarray) -> np.ndarray:
        """The force image (H, W) float32 from one frame's loads (N, M) and the starting image
        ``start`` (H, W; the bicubic image, as the batch path starts from)."""
        ny, nx = self.image_shape
        n_pixels = ny * nx
        operator = np.empty((n_pixels + 1, self.n_loads), dtype=np.float32)  # [F ; -x]
        operator[:n_pixels] = self.forward_scaled
        np.multiply(loads.reshape(-1), -self.inv_noise, out=operator[n_pixels])
        left = np.empty((ny, nx + ny), dtype=np.float32)  # [Z | By]
        left[:, nx:] = self.rows
        # [Bx ; Z] followed by a 1: its last n_pixels + 1 floats are [z, 1]
        buffer = np.empty(nx * nx + n_pixels + 1, dtype=np.float32)
        stencil = buffer[:-1].reshape(nx + ny, nx)
        stencil[:nx] = self.cols
        buffer[-1] = 1.0
        z_flat = buffer[nx * nx :]
        z_left, z_right = left[:, :nx], stencil[nx:]
        p = start.astype(np.float32, copy=True)
        z_right[...] = p
        z_left[...] = p
        smooth = np.empty((ny, nx), dtype=np.float32)
        data = np.empty(n_pixels, dtype=np.float32)
        data_image = data.reshape(ny, nx)
        residual = np.empty(self.n_loads, dtype=np.float32)
        diff = np.empty((ny, nx), dtype=np.float32)
        p_next = np.empty((ny, nx), dtype=np.float32)
        back = self.back
        for weight in self.weights:
            np.dot(z_flat, operator, out=residual)  # z F - x
            np.dot(residual, back, out=data)  # -step * the data term's gradient
            np.dot(left, stencil, out=smooth)  # z - step * the smoothness term's gradient
            smooth += data_image
            smooth += z_right
            np.maximum(smooth, 0.0, out=p_next)  # the prox of p >= 0
            np.subtract(p_next, p, out=diff)
            diff *= weight
            np.add(p_next, diff, out=z_right)
            z_left[...] = z_right
            p, p_next = p_next, p
        return p
