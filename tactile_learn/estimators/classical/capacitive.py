"""Classical estimators of the capacitive array: calibrated cell loads (B, N, M) in newtons (the
front end's output, :mod:`tactile_learn.calibration.capacitive`) -> image (B, 2, N s, M s): the
surface force on every fine pixel (N) and the contact mask (0/1), ``s = samples_per_pitch``.

- ``bicubic`` (:class:`BicubicEstimator`): each cell's load spread over its ``s x s`` pixels by
  bicubic interpolation (Keys' cubic convolution, ``a = -0.5``, edges replicated), then the mask
  by threshold: CapContact's baseline for super-resolving a capacitive image.
- ``deconvolution`` (:class:`DeconvolutionEstimator`): the cover's spreading undone on the fine
  lattice: the non-negative force image ``p`` minimising
  ``|K p - x|^2 / sigma^2 + lambda |grad p|^2`` (``K``: the cover's pressure -> tab-load map of
  :mod:`synth.sensors.capacitive.layer`, ``sigma``: the load noise), by accelerated projected
  gradient (FISTA) from the bicubic image; then the same threshold.

Both decide that a frame has contact where some cell's load exceeds ``contact_sigmas`` load-noise
s.d. (an idle frame has no contact), then threshold the image at ``fraction`` of the largest value
within ``reach`` pixels (each contact against its own peak) and above a per-pixel noise floor.
The defaults were chosen on validation presses (seed 2; ``scripts/capacitive_results.py tune``,
``results/capacitive-tune.json``), not on the test sets: the largest IoU + separation rate among
the settings that miss under 0.5 % of the contacts (a higher floor separates more and loses light
contacts). Contact shapes (outline, area, centroid,
orientation) follow from the image with :mod:`~tactile_learn.estimators.classical.contact_shapes`.

``prepare`` works out the load noise and both levels once (the noise comes from the cell's
response curve: looking it up cost more than a frame's arithmetic). A single frame (batch 1, the
streaming case) goes through 2-D arithmetic on the one image - two small matrix products, the
contact test as one scalar comparison, the local peak by two 1-D maximum filters only where the
frame has contact - with the batch path's results (to float32 rounding of the products); the
deconvolution's iterations on one frame run with its operator folded into a few matrices
(:mod:`.deconvolution_one_frame`, ~3x faster than the batch path at batch 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from scipy import ndimage

from synth.scene import Scene
from synth.sensors.capacitive.config import CapacitiveConfig
from synth.sensors.capacitive.layer import KPA_MM2_TO_N, tab_load_operator
from synth.sensors.capacitive.sensor import load_noise_n
from tactile_learn.estimators.base import Estimator
from tactile_learn.estimators.classical.contact_shapes import threshold_mask
from tactile_learn.estimators.classical.deconvolution_one_frame import OneFrameDeconvolver
from tactile_learn.validation.capacitive import capacitive_input

__all__ = ["BicubicEstimator", "DeconvolutionEstimator", "bicubic_matrix"]


def _keys(d: np.ndarray, a: float = -0.5) -> np.ndarray:
    """Keys' cubic convolution kernel."""
    d = np.abs(d)
    near = ((a + 2) * d - (a + 3)) * d * d + 1
    far = ((a * d - 5 * a) * d + 8 * a) * d - 4 * a
    return np.where(d <= 1, near, np.where(d < 2, far, 0.0))


def bicubic_matrix(n: int, s: int) -> np.ndarray:
    """``(n s, n)``: bicubic interpolation of ``n`` cell values at the centres of ``s`` sub-pixels
    per cell (edge cells replicated beyond the array)."""
    out = np.zeros((n * s, n))
    u = (np.arange(n * s) + 0.5) / s - 0.5  # sub-pixel centres in cell-index units
    base = np.floor(u).astype(int)
    for j in (-1, 0, 1, 2):
        idx = base + j
        np.add.at(out, (np.arange(n * s), np.clip(idx, 0, n - 1)), _keys(u - idx))
    return out


@dataclass(frozen=True)
class _Upsampler:
    rows: np.ndarray  # (H, N) float32
    cols: np.ndarray  # (W, M) float32
    cols_t: np.ndarray  # (M, W) float32, contiguous: ``cols.T`` for one frame's 2-D product
    per_pixel: float  # share of a cell's load on each of its pixels: 1 / s^2

    def image(self, loads: np.ndarray) -> np.ndarray:
        """Bicubic force per fine pixel (N), clipped at 0 (the kernel's negative lobes)."""
        return np.maximum(self.rows @ loads @ self.cols.T, 0.0) * np.float32(self.per_pixel)

    def frame_image(self, loads: np.ndarray) -> np.ndarray:
        """:meth:`image` of one frame's loads (N, M): (H, W), two 2-D products, in place after."""
        force = self.rows @ loads @ self.cols_t
        np.maximum(force, 0.0, out=force)
        force *= np.float32(self.per_pixel)
        return force


@lru_cache(maxsize=8)
def _upsampler(config: CapacitiveConfig) -> _Upsampler:
    g = config.geometry
    s = g.samples_per_pitch
    cols = bicubic_matrix(g.n_cols, s).astype(np.float32)
    return _Upsampler(
        rows=bicubic_matrix(g.n_rows, s).astype(np.float32),
        cols=cols,
        cols_t=np.ascontiguousarray(cols.T),
        per_pixel=1.0 / s**2,
    )


class _ContactImageEstimator(Estimator):
    """Shared by both methods: the input check, the contact test and the thresholded mask (module
    docstring); a method supplies the force image of calibrated loads (:meth:`_force`)."""

    task = "capacitive"

    def __init__(
        self, scene: Scene, threshold: float, reach: int, contact_sigmas: float = 5.0, floor_sigmas: float = 4.0
    ) -> None:
        self.scene = scene
        self.threshold = threshold
        self.reach = reach
        self.contact_sigmas = contact_sigmas
        self.floor_sigmas = floor_sigmas

    def _force(self, loads: np.ndarray, config: CapacitiveConfig) -> np.ndarray:
        raise NotImplementedError

    def _prepare_levels(self) -> None:
        """The contact level and the per-pixel floor (N), from the load noise, once."""
        config: CapacitiveConfig = self.scene.sensor
        noise = load_noise_n(config)
        self.contact_level_ = self.contact_sigmas * noise
        # a cell's noise spread over its pixels
        self.pixel_floor_ = self.floor_sigmas * noise / config.geometry.samples_per_pitch**2

    def predict(self, X: Any) -> np.ndarray:
        return self.predict_checked(capacitive_input(X, self.scene.sensor, "cell_load"))

    def predict_checked(self, loads: np.ndarray) -> np.ndarray:
        up: _Upsampler = self.prepared_state("upsampler_")  # an unprepared estimator fails before any work
        config: CapacitiveConfig = self.scene.sensor
        if not len(loads):
            return np.zeros((0, 2, *config.geometry.image_shape), dtype=np.float32)
        if len(loads) == 1 and type(self).single_force is not _ContactImageEstimator.single_force:
            return self._one_frame(loads[0], self.single_force(loads[0], up))
        force = self._force(loads, config)
        touching = loads.reshape(len(loads), -1).max(axis=1) >= self.contact_level_
        mask = threshold_mask(force, self.threshold, self.pixel_floor_, self.reach) & touching[:, None, None]
        return np.stack([force, mask], axis=1).astype(np.float32)

    def single_force(self, loads: np.ndarray, up: _Upsampler) -> np.ndarray:
        """The force image (H, W) float32 of one frame's loads (N, M), where a method has a
        single-frame path (the base class has none: batch 1 goes through :meth:`_force`)."""
        raise NotImplementedError

    def _one_frame(self, loads: np.ndarray, force: np.ndarray) -> np.ndarray:
        """(1, 2, H, W): the force image (H, W) of one frame's ``loads`` (N, M) and its mask, as
        :meth:`predict_checked` builds them for a batch (the contact test on the frame's largest
        load, the local peak within ``reach``)."""
        out = np.zeros((1, 2, *force.shape), dtype=np.float32)
        out[0, 0] = force
        if not loads.max() >= self.contact_level_:
            return out  # no contact: an empty mask
        if self.reach > 0:
            size = 2 * self.reach + 1
            peak = ndimage.maximum_filter1d(force, size, axis=0, mode="nearest")
            ndimage.maximum_filter1d(peak, size, axis=1, mode="nearest", output=peak)
        else:
            peak = np.float32(force.max(initial=0.0))
        level = np.maximum(self.threshold * peak, self.pixel_floor_)
        np.greater_equal(force, level, out=out[0, 1], casting="unsafe")
        return out


class BicubicEstimator(_ContactImageEstimator):
    name = "bicubic"

    def __init__(
        self,
        scene: Scene,
        threshold: float = 0.4,
        reach: int = 8,
        contact_sigmas: float = 5.0,
        floor_sigmas: float = 4.0,
    ) -> None:
        super().__init__(scene, threshold, reach, contact_sigmas, floor_sigmas)

    def prepare(self) -> BicubicEstimator:
        self.upsampler_ = _upsampler(self.scene.sensor)
        self._prepare_levels()
        return self

    def single_force(self, loads: np.ndarray, up: _Upsampler) -> np.ndarray:
        return up.frame_image(loads)

    def _force(self, loads: np.ndarray, config: CapacitiveConfig) -> np.ndarray:
        up: _Upsampler = self.__dict__.get("upsampler_") or _upsampler(config)
        return up.image(loads)


@dataclass(frozen=True)
class _Deconvolver:
    forward: np.ndarray  # (H W, N M) float32: force per pixel (N) -> tab loads (N), for ``p @ forward``
    step: float  # 1 / Lipschitz constant of the data term's gradient (in noise units)
    noise_n: float


@lru_cache(maxsize=8)
def _deconvolver(config: CapacitiveConfig, smoothness: float) -> _Deconvolver:
    g = config.geometry
    op = tab_load_operator(g, config.cover.thickness_mm)  # (N M, Hp Wp) per kPa
    hp, wp = g.lattice_shape
    ny, nx = g.image_shape
    pad = g.pad_cells
    inside = op.reshape(-1, hp, wp)[:, pad : pad + ny, pad : pad + nx].reshape(op.shape[0], -1)
    forward = (inside / (g.h_mm**2 * KPA_MM2_TO_N)).T  # N on the pixel -> N on each tab
    noise = load_noise_n(config)
    # gradient of |K p - x|^2 / sigma^2 + lambda |grad p|^2 is Lipschitz with 2 (|K|^2 / sigma^2 + 8 lambda)
    lipschitz = 2.0 * (np.linalg.norm(forward, 2) ** 2 / noise**2 + 8.0 * smoothness)
    return _Deconvolver(
        forward=np.ascontiguousarray(forward, dtype=np.float32), step=float(1.0 / lipschitz), noise_n=noise
    )


def _laplacian(p: np.ndarray) -> np.ndarray:
    """``grad^T grad p`` with free (Neumann) edges: the smoothness term's gradient / 2."""
    out = np.zeros_like(p)
    dy = p[:, 1:, :] - p[:, :-1, :]
    dx = p[:, :, 1:] - p[:, :, :-1]
    out[:, 1:, :] += dy
    out[:, :-1, :] -= dy
    out[:, :, 1:] += dx
    out[:, :, :-1] -= dx
    return out


class DeconvolutionEstimator(_ContactImageEstimator):
    name = "deconvolution"

    def __init__(
        self,
        scene: Scene,
        smoothness: float = 1000.0,
        iterations: int = 100,
        threshold: float = 0.2,
        reach: int = 0,
        contact_sigmas: float = 5.0,
        floor_sigmas: float = 4.0,
    ) -> None:
        super().__init__(scene, threshold, reach, contact_sigmas, floor_sigmas)
        self.smoothness = smoothness
        self.iterations = iterations

    def prepare(self) -> DeconvolutionEstimator:
        self.upsampler_ = _upsampler(self.scene.sensor)
        self.deconvolver_ = _deconvolver(self.scene.sensor, float(self.smoothness))
        self._prepare_levels()
        dec: _Deconvolver = self.deconvolver_
        # the single-frame path: the operator folded into a few matrices, once (its module docstring)
        self.one_frame_ = OneFrameDeconvolver(
            dec.forward,
            dec.noise_n,
            dec.step,
            float(self.smoothness),
            self.scene.sensor.geometry.image_shape,
            int(self.iterations),
        )
        return self

    def single_force(self, loads: np.ndarray, up: _Upsampler) -> np.ndarray:
        one: OneFrameDeconvolver = self.prepared_state("one_frame_")
        return one.force(loads, up.frame_image(loads))  # from the bicubic image, as the batch path

    def _force(self, loads: np.ndarray, config: CapacitiveConfig) -> np.ndarray:
        up: _Upsampler = self.__dict__.get("upsampler_") or _upsampler(config)
        dec: _Deconvolver = self.__dict__.get("deconvolver_") or _deconvolver(config, float(self.smoothness))
        b = len(loads)
        ny, nx = config.geometry.image_shape
        target = loads.reshape(b, -1) / np.float32(dec.noise_n)
        forward = dec.forward / np.float32(dec.noise_n)
        p = up.image(loads).reshape(b, -1)
        z, t = p.copy(), 1.0
        step, lam = np.float32(dec.step), np.float32(self.smoothness)
        for _ in range(self.iterations):  # FISTA: projected gradient with Nesterov momentum
            residual = z @ forward - target
            grad = 2.0 * (residual @ forward.T + lam * _laplacian(z.reshape(b, ny, nx)).reshape(b, -1))
            p_next = np.maximum(z - step * grad, 0.0)
            t_next = (1.0 + np.sqrt(1.0 + 4.0 * t * t)) / 2.0
            z = p_next + np.float32((t - 1.0) / t_next) * (p_next - p)
            p, t = p_next, t_next
        return p.reshape(b, ny, nx)
