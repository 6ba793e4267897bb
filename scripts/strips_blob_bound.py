"""How far above the intersection rule can any estimator go on issue 12's smooth random field
(the ``blob_field`` family of ``strips16_ood``)? Three measurements on held-out frames of the family:

1. ``noise``: the rule (and projection, and a shipped model) on the same frames read three ways -
   with the scene's noise, without electrical noise and ADC, and without the 2 % gain spread too:
   the share of the rule's gap to r = 1 that the noise accounts for.
2. ``specialist``: a rule-correction network (:mod:`tactile_learn.nets.strips_rule_correction`)
   trained only on frames of this kind (one blob, the family's ranges widened a little, its own
   seeds), starting at the rule exactly: what a learner that knows the family adds to the rule.
3. ``ambiguity``: least-squares fits of the family's exact generative model (the generator's 17
   uniforms: centre, radius, correlation length, force, four bumps' angle, reach and height) to
   each frame's 32 strip loads, from the nearest frames of a prior library: fields inside the
   family's own prior that explain the readings as well as the truth does, and how far they are
   from it.

    python scripts/strips_blob_bound.py --json results/strips_blob_bound.json
    python scripts/strips_blob_bound.py --n-test 200 --n-train 5000 --epochs 2 --fit-frames 5   # a quick look

Single-threaded (torch and BLAS); the defaults take about 15 minutes on one core.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from typing import Any

import numpy as np

from synth.dataset import simulate_shard
from synth.io import atomic_write_json
from synth.scene import Scene
from synth.sensors.strips import StripSensor
from synth.sensors.strips.mechanics import StripArray
from synth.stimuli import BLOB_BUMPS, BLOB_CUTOFF
from synth.suite import load_suite
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame

FAMILY = "blob_field"
SHARD = 1000  # a shard's frames share one random stream: noise draws would shift the next chunk's shapes


def family_scene() -> Scene:
    return load_suite("strips16_ood").family(FAMILY).scene


def paired(a: np.ndarray, b: np.ndarray) -> dict[str, float]:
    """Mean of ``a - b`` over frames and its standard error."""
    d = a - b
    d = d[np.isfinite(d)]
    return {"mean": float(d.mean()), "se": float(d.std() / np.sqrt(len(d)))}


def quiet(scene: Scene, gain_spread: bool) -> Scene:
    """``scene`` without electrical noise and ADC; ``gain_spread=False``: without the gain spread too."""
    if not gain_spread:
        piezo = dataclasses.replace(scene.sensor.piezo, gain_spread=0.0)
        scene = dataclasses.replace(scene, sensor=dataclasses.replace(scene.sensor, piezo=piezo))
    return scene.with_noise(False)


def draw(scene: Scene, n: int, seed: int, keys: tuple[str, ...]) -> dict[str, np.ndarray]:
    """``n`` frames (a multiple of :data:`SHARD` when above it) in shards of :data:`SHARD`."""
    sizes = [min(SHARD, n - i) for i in range(0, n, SHARD)]
    parts = [simulate_shard(scene, seed, i, size) for i, size in enumerate(sizes)]
    return {k: np.concatenate([p[k] for p in parts]) for k in keys}


READINGS = {"readings": "noisy", "readings_clean": "no_electrical_noise", "readings_ideal": "no_noise_no_gain_spread"}
LATENTS = ("latent_xy_mm", "latent_force_n", "latent_radius_mm", "latent_width_mm", "latent_detail")


def test_frames(n: int, seed: int) -> dict[str, np.ndarray]:
    """The family's frames read three ways; the shapes are the same bit for bit."""
    scene = family_scene()
    noisy = draw(scene, n, seed, ("pressure", "readings", *LATENTS))
    clean = draw(quiet(scene, gain_spread=True), n, seed, ("pressure", "readings"))
    ideal = draw(quiet(scene, gain_spread=False), n, seed, ("pressure", "readings"))
    if not (
        np.array_equal(noisy["pressure"], clean["pressure"]) and np.array_equal(noisy["pressure"], ideal["pressure"])
    ):
        raise RuntimeError("the three readings of the test frames do not share their shapes")
    return {**noisy, "readings_clean": clean["readings"], "readings_ideal": ideal["readings"]}


def training_scene() -> Scene:
    """One blob a frame, the family's ranges widened (force 0.7-7 N, radius 5-11 mm, correlation
    length 2-4.8 mm, margin 6 mm): a specialist of the kind, not of the suite's exact draw."""
    scene = family_scene()
    stimuli = scene.sensor.stimuli
    kind = dataclasses.replace(stimuli.kinds[0], force_n=(0.7, 7.0), radius_mm=(5.0, 11.0), width_mm=(2.0, 4.8))
    stimuli = dataclasses.replace(stimuli, kinds=(kind,), margin_mm=6.0)
    return dataclasses.replace(scene, sensor=dataclasses.replace(scene.sensor, stimuli=stimuli))


# -- 1. noise ---------------------------------------------------------------------------------


def noise_share(test: dict[str, np.ndarray], models: list[str]) -> dict[str, Any]:
    scene = family_scene()
    out: dict[str, Any] = {}
    for method in ["intersection", "projection", *models]:
        estimator = resolve_method("strips", method, scene, threads=1)
        r = {key: pearson_per_frame(estimator.predict(test[key]), test["pressure"]) for key in READINGS}
        out[method] = {name: float(np.nanmean(r[key])) for key, name in READINGS.items()}
        out[method]["_r"] = r
    return out


# -- 2. specialist ------------------------------------------------------------------------------


def specialist(args: argparse.Namespace, test: dict[str, np.ndarray], rule_r: dict[str, np.ndarray]) -> dict[str, Any]:
    import torch

    from tactile_learn.nets.strips_rule_correction import pearson_loss
    from tactile_learn.train_rule_correction import RuleCorrectionConfig, strip_loads_f32, train_rule_correction

    torch.set_num_threads(1)
    keys = ("readings", "pressure")
    ideal = args.specialist_readings == "ideal"
    # the control: the same learner on readings without any noise, where the fits say the field is nearly identified
    scene = quiet(training_scene(), gain_spread=False) if ideal else training_scene()
    test_key = "readings_ideal" if ideal else "readings"
    train = draw(scene, args.n_train, args.train_seed, keys)
    val = draw(scene, args.n_val, args.val_seed, keys)
    config = RuleCorrectionConfig(hidden=args.hidden, epochs=args.epochs, seed=args.train_seed)
    start = time.perf_counter()
    net, history = train_rule_correction(
        family_scene(), (train["readings"], train["pressure"]), (val["readings"], val["pressure"]), config, print
    )
    linear = linear_correction(train, test, test_key, rule_r[test_key])
    print(f"linear correction: {linear}", flush=True)
    with torch.inference_mode():
        pred = net(strip_loads_f32(family_scene(), test[test_key])).numpy()
    r = pearson_per_frame(pred, test["pressure"])
    loss = float(pearson_loss(torch.from_numpy(pred), torch.from_numpy(test["pressure"])))
    return {
        "readings": READINGS[test_key],
        "config": dataclasses.asdict(config),
        "frames": {"train": args.n_train, "val": args.n_val},
        "val_r_by_epoch": history,
        "test_r": float(np.nanmean(r)),
        "test_loss": loss,
        "gain_over_rule": paired(r, rule_r[test_key]),
        "seconds": time.perf_counter() - start,
        "linear_correction": linear,
    }


def linear_correction(
    train: dict[str, np.ndarray], test: dict[str, np.ndarray], test_key: str, rule_r: np.ndarray
) -> dict[str, Any]:
    """The linear posterior mean on the rule's features: the map over the rule map's sum as a ridge
    regression on (the rule's map over its sum, the loads over their total, 1)."""
    scene = family_scene()
    rule = resolve_method("strips", "intersection", scene, threads=1)
    sensor = StripSensor(scene.sensor)

    def features(readings: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        maps = np.concatenate([rule.predict(readings[i : i + 5000]) for i in range(0, len(readings), 5000)])
        maps = maps.reshape(len(readings), -1).astype(np.float64)
        loads = sensor.invert_readings(readings.astype(np.float64))
        scale = maps.sum(1, keepdims=True)
        total = loads.sum(1, keepdims=True)
        ok = (scale[:, 0] > 0) & (total[:, 0] > 0)
        f = np.hstack([maps / np.maximum(scale, 1e-12), loads / np.maximum(total, 1e-12), np.ones((len(maps), 1))])
        return f, scale, ok

    f_tr, scale_tr, ok_tr = features(train["readings"])
    target = train["pressure"].reshape(len(f_tr), -1) / np.maximum(scale_tr, 1e-12)
    gram = f_tr[ok_tr].T @ f_tr[ok_tr]
    ridge = 1e-6 * np.trace(gram) / len(gram)  # a whisker of ridge: the map features are nearly collinear
    weights = np.linalg.solve(gram + ridge * np.eye(len(gram)), f_tr[ok_tr].T @ target[ok_tr])
    f_te, _, ok_te = features(test[test_key])
    fallback = rule.predict(test[test_key]).reshape(len(f_te), -1)
    pred = np.where(ok_te[:, None], f_te @ weights, fallback)  # an idle frame keeps the rule's zero map
    r = pearson_per_frame(pred, test["pressure"])
    return {"test_r": float(np.nanmean(r)), "gain_over_rule": paired(r, rule_r)}


# -- 3. ambiguity: the family's exact generative model -----------------------------------------


class BlobModel:
    """The family's generator as a function of its 17 uniforms ``u`` in [0, 1] (the order of
    :func:`uniforms_of`): the pitch-cell map and the 32 strip loads, on the fine lattice padded
    ``pad`` cells past the array (the force normalised on the whole plane, so the lattice may stop
    short of a blob's tail). Exact to the simulator within 1e-4 of the loads at ``pad`` 8."""

    def __init__(self, scene: Scene, pad: int = 8) -> None:
        self.sensor = StripSensor(scene.sensor)
        mech = StripArray(scene.sensor, pad=pad)
        self.h = mech.h
        self.py = (np.arange(mech.row_y.shape[-1]) - pad + 0.5) * mech.h
        self.px = (np.arange(mech.row_x.shape[-1]) - pad + 0.5) * mech.h
        f64 = np.float64
        self.ops = [(mech.row_y.astype(f64), mech.row_x.astype(f64)), (mech.col_y.astype(f64), mech.col_x.astype(f64))]
        self.cells = (mech.cell_y.astype(f64), mech.cell_x.astype(f64))
        stimuli = scene.sensor.stimuli
        kind = stimuli.kinds[0]
        g = scene.sensor.geometry
        m = stimuli.margin_mm
        self.lo = np.array([m, m, kind.radius_mm[0], kind.width_mm[0], kind.force_n[0]])
        self.hi = np.array(
            [g.n_cols * g.pitch_mm - m, g.n_rows * g.pitch_mm - m, kind.radius_mm[1], kind.width_mm[1], kind.force_n[1]]
        )
        self.floor = np.exp(-0.5 * BLOB_CUTOFF**2)

    def uniforms_of(self, frames: dict[str, np.ndarray], i: int) -> np.ndarray:
        """The uniforms that drew frame ``i`` (its latents)."""
        base = np.r_[
            frames["latent_xy_mm"][i, 0],
            frames["latent_radius_mm"][i, 0],
            frames["latent_width_mm"][i, 0],
            frames["latent_force_n"][i, 0],
        ]
        return np.clip(np.r_[(base - self.lo) / (self.hi - self.lo), frames["latent_detail"][i, 0]], 0.0, 1.0)

    def __call__(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``u`` (W, 17) -> loads (W, N + M), maps (W, N, M) kPa."""
        v = self.lo + u[:, :5] * (self.hi - self.lo)
        x0, y0, radius, sigma, force = v.T
        detail = u[:, 5 : 5 + 3 * BLOB_BUMPS]
        angle = 2 * np.pi * detail[:, 0::3]
        reach = radius[:, None] * np.sqrt(detail[:, 1::3])  # centres uniform over the disc
        height = 0.25 + 0.75 * detail[:, 2::3]
        cx = x0[:, None] + reach * np.cos(angle)
        cy = y0[:, None] + reach * np.sin(angle)
        two_s2 = 2 * sigma[:, None, None] ** 2
        gy = np.exp(-((self.py[None, None, :] - cy[..., None]) ** 2) / two_s2)
        gx = np.exp(-((self.px[None, None, :] - cx[..., None]) ** 2) / two_s2)
        bumps = np.maximum(gy[..., :, None] * gx[..., None, :] - self.floor, 0.0)
        field = np.einsum("wb,wbyx->wyx", height, bumps)
        # each bump's integral over its disc of radius BLOB_CUTOFF sigma: the window carries the force
        area = 2 * np.pi * sigma**2 * (1 - self.floor) - self.floor * np.pi * (BLOB_CUTOFF * sigma) ** 2
        field *= (force * 1000.0 / (height.sum(1) * area))[:, None, None]  # N / mm^2 -> kPa
        law = self.sensor.law
        loads = []
        for axis, (ops_y, ops_x) in zip((2, 1), self.ops, strict=True):
            stress = np.maximum(sum((ops_y[r] @ field) @ ops_x[r].T for r in range(len(ops_y))), 0.0)
            loads.append((1.0 - (1.0 + stress / law.p0_kpa) ** (-law.exponent)).sum(axis))
        cell_y, cell_x = self.cells
        return np.concatenate(loads, axis=1), (cell_y @ field) @ cell_x.T


def ambiguity(
    args: argparse.Namespace, test: dict[str, np.ndarray], rule_maps: dict[str, np.ndarray]
) -> dict[str, Any]:
    from scipy.optimize import least_squares

    scene = family_scene()
    model = BlobModel(scene)
    library = draw(scene, args.n_library, args.library_seed, ("readings", *LATENTS))
    lib_loads = model.sensor.invert_readings(library["readings"].astype(np.float64))
    lib_shape = lib_loads / np.maximum(lib_loads.sum(1, keepdims=True), 1e-9)
    noise = model.sensor.load_noise()
    out: dict[str, Any] = {}
    for key in ("readings_ideal", "readings"):
        rows: dict[str, list[float]] = {
            k: [] for k in ("rule", "best_fit", "cost_truth", "cost_best", "as_good", "mean_as_good")
        }
        loads_all = model.sensor.invert_readings(test[key][: args.fit_frames].astype(np.float64))
        for i, loads in enumerate(loads_all):
            # the noise and the 2 % gain spread, as one standard deviation per strip
            sd = np.sqrt(noise**2 + (0.02 * loads) ** 2)

            def residual(u: np.ndarray, loads: np.ndarray = loads, sd: np.ndarray = sd) -> np.ndarray:
                return (model(u[None])[0][0] - loads) / sd

            shape = loads / max(loads.sum(), 1e-9)
            starts = np.argsort(((lib_shape - shape) ** 2).sum(1))[: args.fit_starts]
            fits = [
                least_squares(
                    residual, np.clip(model.uniforms_of(library, j), 1e-6, 1 - 1e-6), bounds=(0, 1), max_nfev=40
                )
                for j in starts
            ]
            cost_truth = 0.5 * float((residual(model.uniforms_of(test, i)) ** 2).sum())
            costs = np.array([f.cost for f in fits])
            maps = model(np.stack([f.x for f in fits]))[1]
            truth = test["pressure"][i][None]
            r = np.array([pearson_per_frame(m[None], truth)[0] for m in maps])
            good = costs <= cost_truth + 1.0  # within one unit of log-likelihood of the truth's
            rows["rule"].append(float(pearson_per_frame(rule_maps[key][i][None], truth)[0]))
            rows["best_fit"].append(float(r[costs.argmin()]))
            rows["cost_truth"].append(cost_truth)
            rows["cost_best"].append(float(costs.min()))
            rows["as_good"].append(float(r[good].mean()) if good.any() else float("nan"))
            mean_map = maps[good].mean(0) if good.any() else maps[costs.argmin()]
            rows["mean_as_good"].append(float(pearson_per_frame(mean_map[None], truth)[0]))
        arr = {k: np.array(v) for k, v in rows.items()}
        out[READINGS[key]] = {
            "frames": len(loads_all),
            "rule_r": float(np.mean(arr["rule"])),
            "best_fit_r": float(np.mean(arr["best_fit"])),
            "median_cost_truth": float(np.median(arr["cost_truth"])),
            "median_cost_best_fit": float(np.median(arr["cost_best"])),
            "frames_with_a_fit_as_good_as_the_truth": float(np.mean(np.isfinite(arr["as_good"]))),
            "r_of_fits_as_good_as_the_truth": float(np.nanmean(arr["as_good"])),
            "mean_of_those_fits_r": float(np.mean(arr["mean_as_good"])),
            "mean_of_those_fits_minus_rule": paired(arr["mean_as_good"], arr["rule"]),
        }
        print(f"ambiguity ({READINGS[key]}): {out[READINGS[key]]}", flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n-test", type=int, default=4000, help="held-out frames of the family (default 4000)")
    parser.add_argument("--test-seed", type=int, default=31337)
    parser.add_argument("--models", nargs="*", default=["models/strips16.onnx"], help="learned models to compare")
    parser.add_argument("--n-train", type=int, default=300_000)
    parser.add_argument("--train-seed", type=int, default=778)
    parser.add_argument("--n-val", type=int, default=20_000)
    parser.add_argument("--val-seed", type=int, default=777)
    parser.add_argument("--hidden", type=int, default=512)
    parser.add_argument("--epochs", type=int, default=8, help="the specialist's epochs (0: skip it)")
    parser.add_argument(
        "--specialist-readings",
        choices=("noisy", "ideal"),
        default="noisy",
        help="train and test the specialist on the scene's readings or on readings without noise and gain spread",
    )
    parser.add_argument("--fit-frames", type=int, default=60, help="frames fitted per readings kind (0: skip)")
    parser.add_argument("--fit-starts", type=int, default=8)
    parser.add_argument("--n-library", type=int, default=20_000)
    parser.add_argument("--library-seed", type=int, default=999)
    parser.add_argument("--json", help="write the results here")
    args = parser.parse_args(argv)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    seeds = {args.test_seed, args.train_seed, args.val_seed, args.library_seed}
    if len(seeds) < 4:
        parser.error("the test, training, validation and library seeds must differ")
    start = time.perf_counter()
    test = test_frames(args.n_test, args.test_seed)
    noise = noise_share(test, args.models)
    rule_r = noise["intersection"].pop("_r")
    for method, figures in noise.items():
        r = figures.pop("_r", None)
        if r is not None:
            figures["minus_rule"] = paired(r["readings"], rule_r["readings"])
        print(f"{method}: {figures}", flush=True)
    result: dict[str, Any] = {"family": FAMILY, "test": {"frames": args.n_test, "seed": args.test_seed}, "noise": noise}
    if args.epochs > 0:
        result["specialist"] = spec = specialist(args, test, rule_r)
        print(f"specialist: test r {spec['test_r']:.4f}, over the rule {spec['gain_over_rule']}", flush=True)
    if args.fit_frames > 0:
        rule = resolve_method("strips", "intersection", family_scene(), threads=1)
        rule_maps = {key: rule.predict(test[key][: args.fit_frames]) for key in ("readings", "readings_ideal")}
        result["ambiguity"] = ambiguity(args, test, rule_maps)
    result["seconds"] = time.perf_counter() - start
    if args.json:
        atomic_write_json(args.json, result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
