"""Is an FSR frame one round press at all? The check behind the ``p_one_press`` column.

Every FSR estimator (triangulation and the learned model alike) answers with *one* position and
force. Two simultaneous presses, or a large flat indenter, load the six discs in a pattern no
single round press produces, and the estimators still return a position: confident and wrong.

The check pushes the estimate back through the film's forward model (``synth.sensors.fsr``: the
load path to the discs with the nominal gain and the median tip radius, the FSR law) and compares
the six modelled conductances with the measured ones. Because an estimate may be a little off even
for a genuine single press (triangulation's median error is ~3 mm), the estimate is first refined
by a few Levenberg-Marquardt steps on ``(x, y, log F)`` against the readings, from the estimate and
from the sensors' conductance-weighted centroid: the residual is then that of the best single press
near either. (Where only one sensor feels the press, a start on that sensor can stall a few mm from
the truth: triangulation, which puts such presses on the sensor, gets more false flags than the
learned model, whose estimate starts the refinement close to the truth.) ``residual`` is the RMS conductance misfit over
the six sensors divided by the RMS measured conductance plus ``floor_us`` (part gains of +/-6 %
and +/-2 % per press leave a few per cent on genuine presses).

``p_one_press`` is 1 where the residual is at most ``threshold`` and 0 where it is above (a flag,
not a calibrated probability); frames without a detected contact get 0 (as every column does), and
contacts the estimator places outside the triangles (``p_inside <= 0.5``, where its position and
force are extrapolations already) get 0.5: not checked. A frame is flagged where ``p_one_press < 0.5``. The
default threshold was set on normal single presses of unseen films (1 % of them flagged, see
``scripts/fsr_flagging.py``, which also reports how often two presses and flat indenters are caught).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cached_property

import numpy as np
from scipy import special

from synth.scene import Scene
from synth.sensors import fsr
from tactile_learn.fsr_one_frame import OneFrameCheck

__all__ = ["DEFAULT_THRESHOLD", "OnePressCheck", "one_press_check", "with_one_press"]

#: residual above which a frame is flagged (see the module docstring for the rates it gives)
DEFAULT_THRESHOLD = 0.05
#: doubtful frames up to this many are refined from both starts in one pass (fewer numpy calls
#: at batch 1); more are refined from the centroid only where the estimate's start fails (less
#: arithmetic). Both give the same flags: a frame passes if either start's refinement does.
JOINT_STARTS_MAX = 32

_CHECKS: dict[tuple[str, float, int, float], OnePressCheck] = {}


def with_one_press(
    inputs: np.ndarray, prediction: np.ndarray, scene: Scene, check: OnePressCheck | None = None
) -> np.ndarray:
    """An estimate of the first five FSR columns (B, 5) with ``p_one_press`` appended (B, 6) (the
    same check for every method; ``check``: the scene's, prepared by the caller); an estimate that
    has it already is returned as it is."""
    if prediction.ndim != 2 or prediction.shape[1] != 5:
        return prediction
    out = np.empty((len(prediction), 6), dtype=np.float32)
    out[:, :-1] = prediction
    if len(prediction) == 1:  # a single frame (a stream): the check on Python floats
        one = (check or one_press_check(scene)).one_frame
        out[0, -1] = one.p_one_press(inputs[0].tolist(), prediction[0].tolist())
    elif len(prediction):
        out[:, -1] = (check or one_press_check(scene)).p_one_press(inputs, prediction)
    else:
        out[:, -1] = 0.0
    return out


def one_press_check(
    scene: Scene, threshold: float = DEFAULT_THRESHOLD, steps: int = 6, floor_us: float = 5.0
) -> OnePressCheck:
    """The check for ``scene``, built once per scene (digest) and parameters: its film model and
    load path are set up on first use, not on every ``predict`` (at batch 1 that set-up cost more
    than the check itself)."""
    key = (scene.digest, float(threshold), int(steps), float(floor_us))
    check = _CHECKS.get(key)
    if check is None:
        if len(_CHECKS) >= 16:  # a long session over many calibrated films: keep the cache small
            _CHECKS.clear()
        check = _CHECKS[key] = OnePressCheck(scene, threshold, steps, floor_us)
    return check


def _log_force(points: np.ndarray) -> np.ndarray:
    """log of the force column (N) of float32 points (B, >= 3), clipped at 1 mN (a no-force
    estimate still starts somewhere), taken in float64 (numpy's float32 log is not correctly
    rounded and differs between SIMD targets; a float64 log is the single-frame path's
    ``math.log`` to the last bit, or one unit in the last place off for about 1 force in 1,400:
    a start 1e-16 apart, far below anything the flag can see)."""
    return np.log(np.clip(points[:, 2], 1e-3, None).astype(np.float64))


def _start(points: np.ndarray) -> np.ndarray:
    """Float32 points (B, >= 3) (x, y, force) as the refinement's parameters (B, 3): x, y, log force."""
    return np.column_stack([points[:, 0], points[:, 1], _log_force(points)]).astype(np.float64)


_FD_STEP = np.array([0.05, 0.05, 0.01])  # finite-difference steps: mm, mm, log N
_SHIFTS = np.eye(3) * _FD_STEP  # one row per parameter
_EYE3 = np.eye(3)
_STEP_LO, _STEP_HI = np.array([-5.0, -5.0, -1.0]), np.array([5.0, 5.0, 1.0])  # a step's largest move


class OnePressCheck:
    """Residual of the best single round press near an estimate, and the flag (module docstring)."""

    def __init__(self, scene: Scene, threshold: float = DEFAULT_THRESHOLD, steps: int = 6, floor_us: float = 5.0):
        self.scene = scene
        self.threshold = threshold
        self.steps = steps
        self.floor_us = floor_us

    def prepare(self) -> OnePressCheck:
        """Build the film model and load path now rather than on the first check."""
        self._model  # noqa: B018 - cached_property: built here, once
        self._path  # noqa: B018
        self._grid  # noqa: B018
        self.one_frame  # noqa: B018
        return self

    @cached_property
    def one_frame(self) -> OneFrameCheck:
        """The same check for a single frame on Python floats (:mod:`tactile_learn.fsr_one_frame`)."""
        return OneFrameCheck(self)

    @cached_property
    def _model(self) -> tuple[fsr.FsrConfig, fsr.FsrLaw, fsr.Readout, float]:
        config: fsr.FsrConfig = self.scene.sensor
        return (
            config,
            fsr.FsrLaw(config.element),
            fsr.Readout(config.readout),
            float(np.median(config.stimulus.tip_radii_mm)),
        )

    @cached_property
    def _path(self) -> tuple[fsr.Transfer, np.ndarray]:
        """The film's load path and sensor positions, looked up once (``fsr.sensor_loads`` finds
        them on every call: a large share of the check's time at batch 1)."""
        config = self._model[0]
        return fsr.make_transfer(config), fsr.sensor_positions(config.layout)

    @cached_property
    def _grid(self) -> tuple[np.ndarray, float, float, float, float, float, float, int, float, float]:
        """The load table flattened, its grid steps and the film's contact modulus: what
        :meth:`conductance` reads on every call (looked up once)."""
        config = self._model[0]
        transfer = self._path[0]
        dg, ag, table = transfer.d_grid, transfer.a_grid, transfer.table
        lay = config.layout
        e_star = lay.youngs_modulus_mpa / (1.0 - lay.poisson**2)  # as fsr.hertz_radius_mm
        return (
            table.ravel(),
            float(dg[0]),
            float(dg[1] - dg[0]),
            len(dg) - 1.000001,
            float(ag[0]),
            float(ag[1] - ag[0]),
            len(ag) - 1.000001,
            table.shape[1],
            float(dg[-1]),
            float(e_star),
        )

    def conductance(self, params: np.ndarray) -> np.ndarray:
        """Modelled conductances (B, 6) (uS) of presses ``params`` (B, 3): x, y (mm), log force (N),
        the round tip of median radius (``fsr.sensor_loads`` with the law, nominal gain).

        The load path's bilinear lookup (``fsr.Transfer.per_newton``) and the law
        (``fsr.FsrLaw.conductance_us``) written out with the same operations in the same order (the
        results are the same bit for bit; a test compares them), with fewer numpy calls: the check
        calls this a dozen times per batch on a few dozen rows, where each call's fixed cost counts."""
        config, _, _, tip = self._model
        transfer, positions = self._path
        flat, d0, d_step, d_top, a0, a_step, a_top, n_a, d_max, e_star = self._grid
        element = config.element
        force = np.exp(np.clip(params[:, 2], -10.0, 6.0))  # clipped: a diverging step cannot overflow
        distance = np.sqrt(((params[:, None, :2] - positions[None]) ** 2).sum(axis=2))
        radius = np.cbrt(3.0 * np.maximum(force, 0.0) * tip / (4.0 * e_star))[:, None]  # fsr.hertz_radius_mm
        di = np.clip((distance - d0) / d_step, 0.0, d_top)
        ai = np.clip((radius - a0) / a_step, 0.0, a_top)
        i0, j0 = di.astype(np.int64), ai.astype(np.int64)
        fi, fj = di - i0, ai - j0
        gi, gj = 1 - fi, 1 - fj
        k = i0 * n_a + j0
        per_newton = flat[k] * gi * gj + flat[k + n_a] * fi * gj + flat[k + 1] * gi * fj + flat[k + n_a + 1] * fi * fj
        far = distance > d_max
        if far.any():  # beyond the table: the far-field point-load formula (as per_newton)
            area = np.pi * transfer.disc_radius_mm**2
            per_newton = np.where(far, area * transfer.point_kernel(distance), per_newton)
        load = np.maximum(per_newton * force[:, None], 0.0)
        gate = special.expit((load - element.break_force_n) / element.break_width_n)  # width > 0 (validated)
        sat = element.saturation_force_n
        return element.leak_conductance_us + element.conductance_us_per_n * (sat * np.tanh(load * gate / sat))

    def residual(self, readings: np.ndarray, estimate: np.ndarray) -> np.ndarray:
        """Relative conductance misfit (B,) of the best single press near ``estimate`` (B, >= 3)
        for nominal-film ``readings`` (B, 6), or near the sensors' conductance-weighted centroid
        (a second start: an estimate in the wrong triangle must not pass for a misfit)."""
        config, _, readout, _ = self._model
        measured = readout.conductance_us(np.asarray(readings, dtype=np.float64))
        log_force = _log_force(estimate)
        weights = np.maximum(measured - config.element.leak_conductance_us, 0.0) + 1e-12
        centroid = (weights @ self._path[1]) / weights.sum(axis=1, keepdims=True)
        starts = [np.column_stack([estimate[:, 0], estimate[:, 1], log_force]), np.column_stack([centroid, log_force])]
        return np.asarray(np.minimum(*(self._refined_misfit(measured, s.astype(np.float64)) for s in starts)))

    def _refined_misfit(
        self,
        measured: np.ndarray,
        params: np.ndarray,
        stop_below: float | None = None,
        partner: np.ndarray | None = None,
    ) -> np.ndarray:
        """RMS misfit after Levenberg-Marquardt steps from ``params`` (damping per frame: shrunk after
        a step that lowers the misfit, grown after one that does not, which is then undone).

        ``stop_below``: frames whose misfit is at or below it are not stepped further (a step only
        ever lowers the misfit, so their verdict against that threshold is final); the loop ends
        early once every frame is there. Their returned misfit is then the one at that point.

        ``partner`` (with ``stop_below``): row ``i`` and row ``partner[i]`` are two starts of one
        frame, which passes if either does: once one is at or below ``stop_below`` the other is not
        stepped further either (the frame's verdict is decided; only the better misfit counts)."""
        base = self.conductance(params)
        cost = np.sum((measured - base) ** 2, axis=1)
        misfit = self._misfit(measured, base)
        damping = np.full(len(params), 1e-3)
        live = np.arange(len(params)) if stop_below is None else np.flatnonzero(misfit > stop_below)
        if partner is not None and stop_below is not None:
            live = live[misfit[partner[live]] > stop_below]
        for _ in range(self.steps):
            if not live.size:
                break
            p, b, c, d, y = params[live], base[live], cost[live], damping[live], measured[live]
            shifted = (p[None] + _SHIFTS[:, None, :]).reshape(-1, 3)
            jac = (self.conductance(shifted).reshape(3, len(p), -1) - b[None]) / _FD_STEP[:, None, None]
            jac = jac.transpose(1, 2, 0)  # (B, 6, 3)
            jt = jac.transpose(0, 2, 1)
            jtj = jt @ jac
            scale = np.trace(jtj, axis1=1, axis2=2)[:, None, None] + 1e-12
            rhs = jt @ (y - b)[..., None]
            delta = np.linalg.solve(jtj + d[:, None, None] * scale * _EYE3, rhs)[..., 0]
            candidate = p + np.clip(delta, _STEP_LO, _STEP_HI)
            trial = self.conductance(candidate)
            trial_cost = np.sum((y - trial) ** 2, axis=1)
            better = trial_cost < c
            params[live] = np.where(better[:, None], candidate, p)
            base[live] = np.where(better[:, None], trial, b)
            cost[live] = np.where(better, trial_cost, c)
            damping[live] = np.where(better, d / 3.0, d * 5.0)
            if stop_below is not None:
                misfit[live] = self._misfit(y, base[live])
                live = live[misfit[live] > stop_below]
                if partner is not None:
                    live = live[misfit[partner[live]] > stop_below]
        return self._misfit(measured, base)

    def p_one_press(
        self,
        readings: np.ndarray,
        estimate: np.ndarray,
        screen: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> np.ndarray:
        """1 where a detected contact is explained by one round press, else 0 (B,); a frame without
        a detected contact has 0, like every other column of a no-contact estimate.

        Cheapest first (refining only lowers the misfit, so a frame that passes a stage is done):
        the estimate as it is, then refined from the estimate, then refined from the centroid. A
        good estimator's genuine presses mostly pass at the first stage: one forward model.

        ``screen``: for an estimator whose own estimate is a poor start (the half-space kernel's
        triangulation: none of its estimates passes as it is), a function giving a better point
        ``(n, 3)`` (x, y, force; float32) for the frames (row indices of ``readings``) it is handed,
        tried as it is. A frame passes if any stage does, so where the screen comes changes only the
        cost: on a few frames (and on a single frame, :mod:`tactile_learn.fsr_one_frame`) before
        the refinements it may spare; on many after the refinement from the estimate, where
        refining many frames at once costs less than the screen's second closed form for all.
        """
        out = np.zeros(len(estimate), dtype=np.float32)
        detected = estimate[:, 3] > 0.5
        if not detected.any():  # nothing to check (a stream's frames without contact)
            return out
        # outside the triangles (p_inside <= 0.5) position and force are extrapolations already:
        # such frames are not checked (0.5, undecided), which also keeps the check cheap
        out[detected & (estimate[:, 4] <= 0.5)] = 0.5
        contact = np.flatnonzero(detected & (estimate[:, 4] > 0.5))
        if not contact.size:
            return out
        config, _, readout, _ = self._model
        measured = readout.conductance_us(np.asarray(readings, dtype=np.float64)[contact])
        start = _start(estimate[contact])
        passed = self._passes_as_it_is(measured, start)
        doubt = np.flatnonzero(~passed)
        if screen is not None and 0 < doubt.size <= JOINT_STARTS_MAX:  # few frames: the screen first
            passed[doubt] = self._passes_as_it_is(measured[doubt], _start(screen(contact[doubt])))
            doubt = np.flatnonzero(~passed)
        if doubt.size:
            weights = np.maximum(measured[doubt] - config.element.leak_conductance_us, 0.0) + 1e-12
            centroid = (weights @ self._path[1]) / weights.sum(axis=1, keepdims=True)
            second = np.column_stack([centroid, start[doubt, 2]])
            if doubt.size <= JOINT_STARTS_MAX:  # few frames (a stream): both starts in one pass
                n = doubt.size  # row i and row i + n: the two starts of one frame
                both = self._refined_misfit(
                    np.concatenate([measured[doubt]] * 2),
                    np.concatenate([start[doubt], second]),
                    self.threshold,
                    partner=np.concatenate([np.arange(n, 2 * n), np.arange(n)]),
                )
                passed[doubt] = (both <= self.threshold).reshape(2, -1).any(axis=0)
            else:
                passed[doubt] = self._refined_misfit(measured[doubt], start[doubt], self.threshold) <= self.threshold
                still = np.flatnonzero(~passed[doubt])
                if screen is not None and still.size:  # many frames: the screen after this refinement
                    rows = doubt[still]
                    passed[rows] = self._passes_as_it_is(measured[rows], _start(screen(contact[rows])))
                    still = still[~passed[rows]]
                if still.size:
                    refined = self._refined_misfit(measured[doubt[still]], second[still], self.threshold)
                    passed[doubt[still]] = refined <= self.threshold
        out[contact] = passed.astype(np.float32)
        return out

    def _passes_as_it_is(self, measured: np.ndarray, params: np.ndarray) -> np.ndarray:
        """Whether the press ``params`` (B, 3) explains ``measured`` (B, 6) within the threshold."""
        return np.asarray(self._misfit(measured, self.conductance(params)) <= self.threshold)

    def _misfit(self, measured: np.ndarray, model: np.ndarray) -> np.ndarray:
        return np.asarray(
            np.sqrt(np.mean((measured - model) ** 2, axis=1)) / (np.sqrt(np.mean(measured**2, axis=1)) + self.floor_us)
        )
