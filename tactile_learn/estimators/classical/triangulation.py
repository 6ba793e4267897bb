"""Triangulation: the paper's kind of FSR-film algorithm (seed 002), closed form, numpy only.

Steps, per frame (vectorised over the batch and the four triangles):

1. **Readout inversion.** ADC code -> divider conductance -> FSR load on each disc (N), with the
   datasheet law and the nominal part gain 1 (a film calibration, when the scene carries one, has
   already mapped the readings to the nominal film in ``FsrTask.check_inputs``).
2. **Load model.** The disc load of a point load ``P`` at distance ``r`` is modelled as
   ``f = C P (r^2 + h^2)^(-m)``. The default (``kernel="half_space"``, the reference's closed form)
   is the half-space kernel at the sensors' depth: ``h`` = 6 mm, ``m = 5/2``, with ``C`` fitted
   (least squares on log loads) to the film's mean transfer curve over the distances that occur
   inside a triangle. ``kernel="fitted"`` (method ``triangulation_fit``) also fits ``h`` and ``m``
   (:func:`fit_load_model`): the same closed form with an effective kernel, a stronger variant
   than the paper's, reported beside it.
3. **Three-sensor inversion** (reference section 5). With ``g_i = f_i^(-1/m)`` and
   ``K = (C P)^(1/m)`` each sensor gives ``|x - c_i|^2 = K g_i - h^2``. Differences of these
   equations are linear in ``x`` for a given ``K``: ``x = x0 + K x1``; substituting into the first
   leaves ``alpha K^2 + beta K + gamma = 0``. Of the positive roots keep the one whose position lies
   in (or nearest to) the triangle; ``P_raw = K^m / C``.
4. **Force calibration.** ``P = s P_raw``, with ``s`` the median ratio over a fixed grid of
   noise-free presses of the nominal film inside the triangles (:func:`calibrate_force`): the
   film's own finite-element-like calibration, as the paper did. No measured data are used.
5. **Triangle choice.** All four triangles are solved; the winner has the most sensors above the
   break force, then a solution inside its triangle, then the largest summed load, then the
   solution deepest inside.

Documented fallbacks for degenerate cases:

- no real root (noise): ``K`` at the parabola's vertex, ``-beta / (2 alpha)`` (least residual);
- ``alpha ~ 0`` (three equal loads: the contact is at the centroid): the linear root ``-gamma/beta``;
- one sensor of the triangle below the valid load (``min_load_n``, default the break force): its
  load is set to ``fallback_fraction * min_load_n`` (it is known only to be below the threshold)
  and the closed form is used;
- two sensors below it: the contact is put on the remaining sensor, its force is that sensor's
  load over the film's on-axis load per newton, and ``p_inside`` is 0.5: inside or outside
  cannot be told;
- no sensor above it: no contact (all outputs 0).

Output (B, 5) float32, the fsr task's prediction format: ``x_mm, y_mm, force_n, p_contact,
p_inside``; ``p_inside`` is 1 for a solution inside a triangle (within ``inside_tol_mm``), 0 for a
contact located outside every triangle (its position and force are then extrapolations of the
model: flagged, not trusted), 0.5 where it cannot be told.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from scipy import optimize

from synth.scene import Scene
from synth.sensors import fsr
from tactile_learn.estimators.base import Estimator
from tactile_learn.estimators.classical.triangulation_one_frame import OneFrameTriangulation, frame_predictor
from tactile_learn.fsr_check import one_press_check
from tactile_learn.validation.fsr import fsr_check

__all__ = [
    "FittedTriangulationEstimator",
    "LoadModel",
    "TriangleGeometry",
    "TriangulationEstimator",
    "calibrate_force",
    "calibration_presses",
    "fit_load_model",
    "solve_triangles",
    "triangulate",
]


@dataclass(frozen=True)
class LoadModel:
    """``f = C P (r^2 + h^2)^(-m)``: disc load against applied load and distance.

    ``force_scale``/``force_exponent`` calibrate the force: ``P = force_scale * P_raw^force_exponent``
    where ``P_raw = K^m / C`` comes from the closed form (1 and 1: uncalibrated).
    """

    c: float
    h_mm: float
    m: float
    rms_log_error: float
    force_scale: float = 1.0
    force_exponent: float = 1.0
    #: the film's disc load per newton straight under the load (for the one-sensor fallback)
    on_axis: float = 0.0

    def load(self, r_mm: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        return self.c * np.asarray(force_n) * (np.asarray(r_mm) ** 2 + self.h_mm**2) ** (-self.m)

    def force(self, k: np.ndarray) -> np.ndarray:
        """Calibrated force from the closed form's ``K`` (``K >= 0``)."""
        raw = np.maximum(k, 0.0) ** self.m / self.c  # c > 0
        return self.force_scale * raw**self.force_exponent


def fit_load_model(config: fsr.FsrConfig, kernel: str = "half_space", r_max_mm: float | None = None) -> LoadModel:
    """:class:`LoadModel` for the film: least squares on its noise-free disc load per newton.

    ``kernel="half_space"``: the reference's kernel, ``h`` = the sensors' depth and ``m = 5/2``;
    only ``C`` is fitted. ``kernel="fitted"``: ``C``, ``h`` and ``m`` are all fitted (for each ``h``
    on a grid the fit of ``log f = log C - m log(r^2 + h^2)`` is linear; the best ``h`` wins).
    Distances ``0..r_max_mm`` (default: the triangle side, the farthest a sensor of a contact's own
    triangle can be), Hertz radius of the median force on the median tip.
    """
    lay, st = config.layout, config.stimulus
    r_max = lay.side_mm if r_max_mm is None else r_max_mm
    r = np.linspace(0.0, r_max, 161)
    force = math.sqrt(st.force_range_n[0] * st.force_range_n[1])
    a = fsr.hertz_radius_mm(np.array(force), np.array(float(np.median(st.tip_radii_mm))), lay)
    q = fsr.make_transfer(config).per_newton(r, np.full_like(r, float(a)))
    y = np.log(np.maximum(q, 1e-300))  # q > 0 for any kernel with positive weight
    best: LoadModel | None = None
    if kernel == "half_space":
        h_grid = np.array([lay.sensor_depth_mm])
    elif kernel == "fitted":
        h_grid = np.linspace(0.5, 4.0 * max(lay.sensor_depth_mm, config.transfer.share_length_mm), 400)
    else:
        raise ValueError(f"kernel must be 'half_space' or 'fitted', got {kernel!r}")

    def fit_at(h: float) -> LoadModel | None:
        lx = np.log(r * r + h * h)
        if kernel == "fitted":
            design = np.stack([np.ones_like(lx), -lx], axis=1)
            coef, *_ = np.linalg.lstsq(design, y, rcond=None)
            log_c, m = float(coef[0]), float(coef[1])
        else:
            m = 2.5
            log_c = float(np.mean(y + m * lx))
        if m <= 0.05:
            return None
        err = float(np.sqrt(np.mean((log_c - m * lx - y) ** 2)))
        return LoadModel(c=math.exp(log_c), h_mm=float(h), m=m, rms_log_error=err, on_axis=float(q[0]))

    for h in h_grid:
        candidate = fit_at(float(h))
        if candidate is not None and (best is None or candidate.rms_log_error < best.rms_log_error):
            best = candidate

    def error_at(h: float) -> float:
        model = fit_at(h)
        return math.inf if model is None else model.rms_log_error

    if best is not None and len(h_grid) > 1:  # refine h between the grid's neighbours
        step = float(h_grid[1] - h_grid[0])
        result = optimize.minimize_scalar(
            error_at,
            bounds=(max(best.h_mm - step, 1e-3), best.h_mm + step),
            method="bounded",
            options={"xatol": 1e-4},
        )
        refined = fit_at(float(result.x))
        if refined is not None and refined.rms_log_error <= best.rms_log_error:
            best = refined
    if best is None:  # pragma: no cover - only for a kernel that does not fall with distance
        raise ValueError("the film's transfer does not decrease with distance; triangulation cannot be fitted")
    return best


@dataclass(frozen=True)
class TriangleGeometry:
    """What the closed form needs of the four triangles, computed once per layout."""

    tris: np.ndarray  # (4, 3) sensor indices
    corners: np.ndarray  # (4, 3, 2)
    a_inv: np.ndarray  # (4, 2, 2): inverse of the rows -2 (c_i - c_1), i = 2, 3
    x0: np.ndarray  # (4, 2)
    u: np.ndarray  # (4, 2): x0 - c_1
    bary_inv: np.ndarray  # (4, 2, 2): inverse of [c_2 - c_1, c_3 - c_1] (columns)
    height_mm: float

    @classmethod
    def from_positions(cls, positions: np.ndarray) -> TriangleGeometry:
        tris = np.array(fsr.TRIANGLES)
        corners = positions[tris]
        c1 = corners[:, 0]
        # non-singular: the three sensors of a triangle are not collinear
        a_inv = np.linalg.inv(-2.0 * (corners[:, 1:] - c1[:, None, :]))
        e = (corners[:, 1:] ** 2).sum(-1) - (c1**2).sum(-1)[:, None]
        x0 = -np.einsum("tij,tj->ti", a_inv, e)
        edges = np.stack([corners[:, 1] - c1, corners[:, 2] - c1], axis=-1)  # (4, 2, 2) columns
        height = math.sqrt(3.0) / 2.0 * float(np.linalg.norm(corners[0, 1] - corners[0, 0]))
        return cls(tris, corners, a_inv, x0, x0 - c1, np.linalg.inv(edges), height)

    def own_barycentric(self, xy: np.ndarray) -> np.ndarray:
        """(..., 4, 3) barycentric coordinates of points ``xy`` (..., 4, 2) in their own triangle."""
        l12 = np.einsum("tij,...tj->...ti", self.bary_inv, xy - self.corners[:, 0])
        return np.concatenate([1.0 - l12.sum(-1, keepdims=True), l12], axis=-1)


_ONE_FRAME, _FLOAT32 = (1, fsr.N_SENSORS), np.dtype(np.float32)  # a single frame that takes the fast path
_ROW = (1, 6)  # a single frame's result
_SCREEN_MODELS: dict[tuple[str, float], LoadModel] = {}


def _screen_model(scene: Scene, min_load_n: float) -> LoadModel:
    """The fitted kernel's calibrated load model of ``scene``'s film (as ``triangulation_fit``'s),
    built once per scene and valid load (the fit takes ~0.5 s)."""
    key = (scene.digest, float(min_load_n))
    model = _SCREEN_MODELS.get(key)
    if model is None:
        if len(_SCREEN_MODELS) >= 16:  # a long session over many calibrated films: keep the cache small
            _SCREEN_MODELS.clear()
        model = _SCREEN_MODELS[key] = calibrate_force(scene.sensor, fit_load_model(scene.sensor, "fitted"), min_load_n)
    return model


@functools.lru_cache(maxsize=8)
def _geometry(layout: fsr.LayoutConfig) -> TriangleGeometry:
    return TriangleGeometry.from_positions(fsr.sensor_positions(layout))


def solve_triangles(
    loads: np.ndarray,
    geometry: TriangleGeometry,
    model: LoadModel,
    min_load_n: float,
    fallback_fraction: float = 0.5,
    inside_tol_mm: float = 1.0,
) -> dict[str, np.ndarray]:
    """Closed-form solution in each of the four triangles, with the documented fallbacks.

    ``loads`` (B, 6) disc loads (N); returns per triangle (B, 4) arrays: ``xy`` (B, 4, 2),
    ``force``, ``n_valid`` (sensors above ``min_load_n``), ``inside`` (bool), ``depth`` (how far
    inside, in barycentric units: negative outside), ``total`` (summed loads).
    """
    tris, corners = geometry.tris, geometry.corners
    f = loads[:, tris]  # (B, 4, 3)
    valid = f >= min_load_n
    n_valid = valid.sum(axis=-1)
    # a load below the threshold is only known to be small: use a fraction of the threshold
    f_used = np.where(valid, f, fallback_fraction * min_load_n)
    f_used = np.maximum(f_used, 1e-9)  # > 0 for the negative power below
    g = f_used ** (-1.0 / model.m)  # (B, 4, 3)
    a_inv, x0, u = geometry.a_inv, geometry.x0, geometry.u
    dg = g[..., 1:] - g[..., :1]  # (B, 4, 2)
    x1 = np.einsum("tij,btj->bti", a_inv, dg)  # (B, 4, 2)
    h2 = model.h_mm**2
    alpha = (x1**2).sum(-1)  # (B, 4) >= 0
    beta = 2.0 * np.einsum("ti,bti->bt", u, x1) - g[..., 0]
    gamma = (u**2).sum(-1) + h2  # (4,) > 0
    gamma = np.broadcast_to(gamma, alpha.shape)
    disc = beta * beta - 4.0 * alpha * gamma
    tiny = alpha <= 1e-12 * np.maximum(beta * beta, 1e-300)
    sq = np.sqrt(np.maximum(disc, 0.0))
    safe_alpha = np.where(tiny, 1.0, alpha)  # the linear branch is used where alpha ~ 0
    safe_beta = np.where(np.abs(beta) > 1e-300, beta, -1e-300)  # beta < 0 whenever a root is > 0
    roots = np.stack([(-beta - sq) / (2 * safe_alpha), (-beta + sq) / (2 * safe_alpha)], axis=-1)
    vertex = -beta / (2 * safe_alpha)
    roots = np.where((disc < 0)[..., None], vertex[..., None], roots)
    roots = np.where(tiny[..., None], (-gamma / safe_beta)[..., None], roots)
    xy_roots = x0[None, :, None, :] + roots[..., None] * x1[:, :, None, :]  # (B, 4, 2, 2)
    lam = geometry.own_barycentric(np.moveaxis(xy_roots, 2, 1))  # (B, 2, 4, 3)
    lam = np.moveaxis(lam, 1, 2)  # (B, 4, 2, 3)
    depth = lam.min(axis=-1)  # (B, 4, 2): > 0 inside
    depth = np.where(roots > 0, depth, -np.inf)  # K = (C P)^(1/m) must be positive
    pick = np.argmax(depth, axis=-1)  # (B, 4)
    k_best = np.take_along_axis(roots, pick[..., None], -1)[..., 0]
    xy = np.take_along_axis(xy_roots, pick[..., None, None], 2)[:, :, 0]
    best_depth = np.take_along_axis(depth, pick[..., None], -1)[..., 0]
    force = model.force(k_best)
    inside = best_depth >= -inside_tol_mm / geometry.height_mm
    # fewer than two valid sensors: put the contact on the strongest one of the triangle
    strongest = np.argmax(f, axis=-1)  # (B, 4)
    on_sensor = corners[np.arange(4)[None, :], strongest]  # (B, 4, 2)
    f_max = np.take_along_axis(f, strongest[..., None], -1)[..., 0]
    one = n_valid <= 1
    xy = np.where(one[..., None], on_sensor, xy)
    # on the sensor's axis: the film's own on-axis load per newton (the kernel's peak is where
    # the closed form's model is least faithful); on_axis > 0 for any film that loads its discs
    force = np.where(one, np.maximum(f_max, 0.0) / max(model.on_axis, 1e-300), force)
    force = np.where(np.isfinite(force), force, 0.0)
    return {
        "xy": xy,
        "force": force,
        "n_valid": n_valid,
        "inside": inside & ~one,
        "depth": np.where(one, 0.0, best_depth),
        "total": f.sum(axis=-1),
    }


def triangulate(
    loads: np.ndarray,
    config: fsr.FsrConfig,
    model: LoadModel,
    min_load_n: float,
    fallback_fraction: float = 0.5,
    inside_tol_mm: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Estimate (B, 5) from disc loads (B, 6), and the number of valid sensors used (B,)."""
    contact = loads.max(axis=1, initial=0.0) >= min_load_n
    if not contact.all():  # frames without a contact are all zeros (and no sensor is valid): not solved
        out = np.zeros((len(loads), 5), dtype=np.float64)
        n_valid = np.zeros(len(loads), dtype=np.int64)
        if contact.any():
            out[contact], n_valid[contact] = triangulate(
                loads[contact], config, model, min_load_n, fallback_fraction, inside_tol_mm
            )
        return out, n_valid
    geometry = _geometry(config.layout)
    sol = solve_triangles(loads, geometry, model, min_load_n, fallback_fraction, inside_tol_mm)
    # winner: most valid sensors, then inside, then the largest summed load (the contact's own
    # triangle carries most), then the deepest inside
    total = sol["total"] / np.maximum(sol["total"].max(axis=1, keepdims=True), 1e-300)  # in [0, 1]
    score = sol["n_valid"] * 1e6 + sol["inside"] * 1e5 + np.round(total, 3) * 1e3 + np.clip(sol["depth"], -1, 1)
    best = np.argmax(score, axis=1)
    rows = np.arange(len(loads))
    n_valid = sol["n_valid"][rows, best]
    out = np.zeros((len(loads), 5), dtype=np.float64)
    out[:, 0:2] = sol["xy"][rows, best]
    out[:, 2] = sol["force"][rows, best]
    out[:, 3] = 1.0  # every frame here has a contact
    out[:, 4] = np.where(n_valid <= 1, 0.5, sol["inside"][rows, best].astype(np.float64))
    return out, n_valid


def calibration_presses(config: fsr.FsrConfig, per_side: int = 8, n_forces: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """A fixed grid of presses for the force calibration: a barycentric lattice in every triangle
    (``per_side`` steps) times ``n_forces`` forces spanning the upper decade of the scene's range."""
    tri = fsr.triangle_vertices(config.layout)
    steps = [(i, j) for i in range(per_side + 1) for j in range(per_side + 1 - i)]
    lam = np.array([(i / per_side, j / per_side, 1.0 - (i + j) / per_side) for i, j in steps])
    points = np.einsum("pk,tkd->tpd", lam, tri).reshape(-1, 2)
    points = np.unique(np.round(points, 6), axis=0)
    hi = config.stimulus.force_range_n[1]
    lo = max(config.stimulus.force_range_n[0], hi / 10.0)
    forces = np.geomspace(lo, hi, n_forces)
    xy = np.repeat(points, len(forces), axis=0)
    return xy, np.tile(forces, len(points))


def calibrate_force(config: fsr.FsrConfig, model: LoadModel, min_load_n: float) -> LoadModel:
    """Force scale ``s`` of ``P = s P_raw``: the median ratio of true to raw force over noise-free,
    unquantised presses of the nominal film (:func:`calibration_presses`) that load all three
    sensors of their triangle, as the paper calibrated its film with FEA. (A fitted exponent as
    well is fragile: presses whose far sensors sit near the break dilute the regression.)"""
    xy, force = calibration_presses(config)
    sim = fsr.FsrSimulator(config, ("readings",), noise=False)
    tip = float(np.median(config.stimulus.tip_radii_mm))
    loads = sim.loads_from_readings(sim.forward(xy, force, tip, quantise=False))
    raw, n_valid = triangulate(loads, config, model, min_load_n)
    use = (n_valid == 3) & (raw[:, 2] > 0)
    if not use.any():  # pragma: no cover - a film whose sensors never see a triangle's presses
        return model
    scale = float(np.exp(np.median(np.log(force[use] / raw[use, 2]))))  # both > 0 where used
    return dataclasses.replace(model, force_scale=scale, force_exponent=1.0)


class TriangulationEstimator(Estimator):
    """Closed-form triangulation on the FSR film (see the module docstring)."""

    task: ClassVar[str] = "fsr"
    name = "triangulation"
    kind = "classical"
    backend = "numpy"

    def __init__(
        self,
        scene: Scene,
        kernel: str = "half_space",
        min_load_n: float | None = None,
        fallback_fraction: float = 0.5,
        inside_tol_mm: float = 1.0,
        calibrate: bool = True,
    ) -> None:
        self.scene = scene
        self.kernel = kernel
        self.min_load_n = min_load_n
        self.fallback_fraction = fallback_fraction
        self.inside_tol_mm = inside_tol_mm
        self.calibrate = calibrate

    def _threshold(self) -> float:
        config: fsr.FsrConfig = self.scene.sensor
        return config.element.break_force_n if self.min_load_n is None else float(self.min_load_n)

    def prepare(self) -> TriangulationEstimator:
        """Fit the load model to the scene's film (no data needed: the film's physics is known),
        and build the readout inverse and the one-press check, once."""
        if "model_" not in self.__dict__:
            model = fit_load_model(self.scene.sensor, self.kernel)
            if self.calibrate:
                model = calibrate_force(self.scene.sensor, model, self._threshold())
            self.model_ = model
            self.simulator_ = fsr.FsrSimulator(self.scene.sensor, ("readings",), noise=False)  # readout inverse
            # the readout inverse builds its lookup table on first use: build it here, not in predict
            self.simulator_.loads_from_readings(np.zeros((1, fsr.N_SENSORS), dtype=np.float32))
            self.check_ = one_press_check(self.scene).prepare()
            self.input_check_ = fsr_check(self.scene.sensor)
            # the single-frame path: every ADC code's disc load by the batch inverse, once
            levels = fsr.Readout(self.scene.sensor.readout).full_scale + 1
            self.one_frame_ = OneFrameTriangulation(
                _geometry(self.scene.sensor.layout),
                model,
                self._threshold(),
                self.fallback_fraction,
                self.inside_tol_mm,
                self.simulator_.loads_from_readings(np.arange(levels, dtype=np.float64)),
                self.simulator_.loads_from_readings,
                # (low, high, strict) of a frame that passes the input check unchanged; None for a
                # calibrated film (its readings are mapped): such frames take the batch path
                self.input_check_.bounds(),
            )
            # the one-press check's screen (fsr_check.OnePressCheck.p_one_press): the half-space
            # kernel's estimate is a poor start for the check (none of the latency set's presses
            # passes as it is; each needs one or two refinement steps), the fitted kernel's
            # solution of the same loads mostly passes as it is
            self.screen_model_ = None if self.kernel == "fitted" else _screen_model(self.scene, self._threshold())
            self.screen_one_frame_ = (
                None
                if self.screen_model_ is None
                else OneFrameTriangulation(
                    _geometry(self.scene.sensor.layout),
                    self.screen_model_,
                    self._threshold(),
                    self.fallback_fraction,
                    self.inside_tol_mm,
                    self.one_frame_.loads_of_codes_array,
                    self.simulator_.loads_from_readings,
                )
            )
            self.frame_predictor_ = frame_predictor(self.one_frame_, self.check_.one_frame, self.screen_one_frame_)
            self.one_frame_run_ = self._one_frame_run()
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        try:
            run = self.one_frame_run_
        except AttributeError:  # not prepared: the clear error
            run = self.prepared_state("one_frame_run_")
        out = run(X)  # a plain single frame (a stream), or None
        if out is not None:
            return out
        return self.predict_checked(self.prepared_state("input_check_")(X))

    def one_frame_run(self) -> Callable[[Any], np.ndarray | None] | None:
        """``run(frames)``: :meth:`predict` of a plain single frame, ``None`` for anything else
        (another type, shape or dtype, or a code that is no key of the code -> load table: NaN,
        inf, out of range, not whole). :class:`~tactile_learn.frame_stream.FrameStream` tries it
        first on every frame. ``None`` for a calibrated film (its readings are mapped first: no
        code is a key), whose streams take the checked path."""
        one: OneFrameTriangulation = self.prepared_state("one_frame_")
        return self.one_frame_run_ if one.load_of_code else None

    def _one_frame_run(self) -> Callable[[Any], np.ndarray | None]:
        """:meth:`one_frame_run`, built in :meth:`prepare`: a frame of six whole codes that the
        input check passes as they are is six keys of the code -> load table (the look-up is the
        check), then :func:`.triangulation_one_frame.frame_predictor`."""
        table, predict_loads, m = self.one_frame_.load_of_code, self.frame_predictor_, self.one_frame_.min_load
        ndarray, zeros = np.ndarray, np.zeros

        def run(frames: Any) -> np.ndarray | None:
            if type(frames) is ndarray and frames.shape == _ONE_FRAME and frames.dtype is _FLOAT32:
                codes = frames.tolist()[0]
                c0, c1, c2, c3, c4, c5 = codes
                try:
                    l0, l1, l2, l3, l4, l5 = table[c0], table[c1], table[c2], table[c3], table[c4], table[c5]
                except KeyError:  # the general check: its clear error, or the general path
                    return None
                if l0 < m and l1 < m and l2 < m and l3 < m and l4 < m and l5 < m:  # most frames of a stream
                    return zeros(_ROW, _FLOAT32)  # no contact: every column 0
                return predict_loads(codes, (l0, l1, l2, l3, l4, l5), True)
            return None

        return run

    def _predict_frame(self, one: OneFrameTriangulation, codes: list[float]) -> np.ndarray:
        """(1, 6) for one checked frame of nominal-film codes, on Python floats."""
        predict_loads: Callable[..., np.ndarray] = self.frame_predictor_
        return predict_loads(codes, one.loads(codes))

    def frame_runner(self) -> Callable[[np.ndarray], np.ndarray]:
        """A function of one validated frame ``(1, 6)`` giving what :meth:`predict_checked` gives,
        with the single-frame state looked up once (:class:`~tactile_learn.frame_stream.FrameStream`
        calls it for the single frames of an ungated stream, after its own check)."""
        one: OneFrameTriangulation = self.prepared_state("one_frame_")
        predict_loads: Callable[..., np.ndarray] = self.frame_predictor_
        loads = one.loads

        def run_frame(x: np.ndarray) -> np.ndarray:
            codes = x.tolist()[0]
            return predict_loads(codes, loads(codes))

        return run_frame

    def predict_checked(self, readings: np.ndarray) -> np.ndarray:
        if len(readings) == 1:
            return self._predict_frame(self.prepared_state("one_frame_"), readings.tolist()[0])
        return self.predict_batch(readings)

    def predict_batch(self, readings: np.ndarray) -> np.ndarray:
        """The vectorised path for checked nominal-film readings (B, 6), any B (``predict`` takes
        it from two frames up; the single-frame path gives the same results)."""
        model: LoadModel = self.prepared_state("model_")
        config: fsr.FsrConfig = self.scene.sensor
        loads = self.simulator_.loads_from_readings(readings)
        out, _ = triangulate(loads, config, model, self._threshold(), self.fallback_fraction, self.inside_tol_mm)
        result = np.empty((len(out), 6), dtype=np.float32)
        result[:, :5] = out
        screen = None
        screen_model: LoadModel | None = self.screen_model_
        if screen_model is not None:
            options = (self._threshold(), self.fallback_fraction, self.inside_tol_mm)

            def screen(rows: np.ndarray) -> np.ndarray:  # the fitted kernel's solution (float32)
                return triangulate(loads[rows], config, screen_model, *options)[0][:, :3].astype(np.float32)

        result[:, 5] = self.check_.p_one_press(readings, result[:, :5], screen)  # reads the float32 estimate
        return result


class FittedTriangulationEstimator(TriangulationEstimator):
    """Triangulation with the fitted effective kernel (``h`` and ``m`` fitted too)."""

    name = "triangulation_fit"

    def __init__(
        self,
        scene: Scene,
        kernel: str = "fitted",
        min_load_n: float | None = None,
        fallback_fraction: float = 0.5,
        inside_tol_mm: float = 1.0,
        calibrate: bool = True,
    ) -> None:
        super().__init__(scene, kernel, min_load_n, fallback_fraction, inside_tol_mm, calibrate)
