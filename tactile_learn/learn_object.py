"""A specialist for an object nobody modelled, from unlabelled readings of it (torch; ``tactile-learn learn-object``).

The general strip model has a prior for shapes it was trained on only; for one object, a specialist
trained on that object's frames is far ahead of the rule (docs/strips.md: +0.144 in r on round 12's
objects). Such frames come from a simulator that knows the object. Here they come from the sensor:

1. the object's template is fitted to its readings alone (:mod:`tactile_learn.object_tomography`);
2. the template is rendered through the sensor model (:func:`render_frames`): at uniform angles, at the
   centres the fit found (so the array's edge cuts the object as it did), each frame's load matched to
   one observed frame's load (the forces the object was pressed with), the template's parts varied
   by a smooth random factor (a lognormal field, 4 cells across, ``vary`` its log standard deviation:
   parts of real objects do not press equally every time), every strip's gain drawn as the scene
   draws it, the scene's noise and ADC;
3. the objects' expert (``strips16_generic``) is fine-tuned on those frames (``train``) and exported
   with its card (``export``).

Every step's output stays in the folder, with ``object.json`` (written last) recording the frames
used, the fit and the command. The specialist is a strip model like any other: ``eval``, ``run`` and
``tactile-learn objects`` (a router over several) take it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from synth.dataset import write_shards
from synth.errors import ConfigError
from synth.io import atomic_write_json
from synth.scene import Scene
from synth.sensors.strips.physics import StripSensor
from synth.sensors.strips.stimuli import OUTPUTS
from tactile_learn.learned_objects import OBJECT_FILE, OBJECT_KIND, RENDERED_TRAIN, RENDERED_VAL, readings_record
from tactile_learn.object_frames import frame_loads, readable_object_frames
from tactile_learn.object_tomography import ObjectTemplate, TomographyConfig, fit_template, rotated

__all__ = ["LearnConfig", "learn_object", "render_frames", "write_rendered"]


@dataclass(frozen=True)
class LearnConfig:
    """``frames``: readings fitted (the first ones with an object on the array); ``n_train`` / ``n_val``:
    rendered frames; ``vary``: log standard deviation of the parts' random factor; ``epochs`` / ``lr``:
    the fine-tune's; ``init``: the weights it starts from; ``min_frames``: fewer usable frames is an error."""

    frames: int = 1500
    n_train: int = 24000
    n_val: int = 2000
    vary: float = 0.4
    epochs: int = 8
    lr: float = 3e-4
    init: str = "strips16_generic"
    seed: int = 0
    threads: int = 1
    min_frames: int = 200

    def __post_init__(self) -> None:
        if self.frames < self.min_frames or self.min_frames < 1:
            raise ConfigError(
                f"frames: expected at least min_frames ({self.min_frames}) frames to fit, got {self.frames}"
            )
        if self.n_train < 256 or self.n_val < 64:
            raise ConfigError(
                f"n_train >= 256 and n_val >= 64 rendered frames expected, got {self.n_train}, {self.n_val}"
            )
        if not 0 <= self.vary <= 2:
            raise ConfigError(f"vary: expected a log standard deviation in [0, 2], got {self.vary}")
        if self.epochs < 1 or not 0 < self.lr < 1:
            raise ConfigError(f"epochs >= 1 and lr in (0, 1) expected, got {self.epochs}, {self.lr}")


def _part_factor(n: int, size: int, vary: float, rng: np.random.Generator) -> np.ndarray:
    """(n, size, size) lognormal factors with mean 1, correlated over ~4 cells (a part's extent)."""
    if vary == 0:
        return np.ones((n, size, size))
    noise = rng.standard_normal((n, size, size))
    f = np.fft.fftfreq(size)
    kernel = np.exp(-2 * (np.pi * 4.0) ** 2 * (f[:, None] ** 2 + f[None, :] ** 2))
    field = np.fft.ifft2(np.fft.fft2(noise) * kernel).real
    field /= field.std(axis=(1, 2), keepdims=True) + 1e-12
    out: np.ndarray = np.exp(vary * field - 0.5 * vary**2)
    return out


def _place(rot: np.ndarray, centres: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(n, H, W): each rotated template with its middle on its centre cell, cut by the array's edge."""
    n, size = len(rot), rot.shape[-1]
    h, w = shape
    fields = np.zeros((n, h, w))
    for k in range(n):
        y0, x0 = int(centres[k, 0]) - size // 2, int(centres[k, 1]) - size // 2
        ys, xs, ye, xe = max(0, y0), max(0, x0), min(h, y0 + size), min(w, x0 + size)
        if ye > ys and xe > xs:
            fields[k, ys:ye, xs:xe] = rot[k, ys - y0 : ye - y0, xs - x0 : xe - x0]
    return fields


def _match_load(fields: np.ndarray, target: np.ndarray, sensor: StripSensor, gains: np.ndarray) -> np.ndarray:
    """Each field scaled (kPa per unit) so its noise-free load is its target: bisection on log10 of the
    scale over [-3, 5] (the load grows monotonically with the scale; 24 halvings: 5e-7 decades)."""
    lo, hi = np.full(len(fields), -3.0), np.full(len(fields), 5.0)
    for _ in range(24):
        mid = 0.5 * (lo + hi)
        clean = sensor.forward(fields * (10.0**mid)[:, None, None], gains=gains)["readings_clean"]
        below = frame_loads(clean, sensor)[2] < target
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    scaled: np.ndarray = fields * (10.0 ** (0.5 * (lo + hi)))[:, None, None]
    return scaled


def render_frames(
    template: ObjectTemplate, scene: Scene, n: int, rng: np.random.Generator, vary: float
) -> dict[str, np.ndarray]:
    """``n`` frames of the fitted object through ``scene``'s sensor: ``readings`` (n, N+M) and the
    intersection map ``pressure`` (n, N, M), as a dataset stores them."""
    sensor = StripSensor(scene.sensor)
    if sensor.field_pitch_mm != template.cell_mm:
        raise ConfigError(
            f"the template's cells are {template.cell_mm} mm, the scene's lattice {sensor.field_pitch_mm} mm"
        )
    angles = torch.from_numpy(rng.uniform(0.0, 2 * np.pi, n).astype(np.float32))
    centres = template.centres[rng.integers(0, len(template.centres), n)]
    target = template.total_load[rng.integers(0, len(template.total_load), n)]
    with torch.no_grad():
        rot = rotated(torch.from_numpy(template.template), angles).numpy().astype(np.float64)
    rot *= _part_factor(n, rot.shape[-1], vary, rng)
    fields = _place(rot, centres, sensor.field_shape)
    spread = scene.sensor.piezo.gain_spread
    gains = np.clip(1.0 + spread * rng.standard_normal((n, sensor.n_strips)), 0.5, 1.5).astype(np.float32)
    fields = _match_load(fields, target, sensor, gains)
    out = sensor.forward(fields, gains=gains, rng=rng, noise=scene.noise)
    return {"readings": out["readings"], "pressure": out["pressure"]}


def write_rendered(
    template: ObjectTemplate, scene: Scene, n: int, seed: int, out: Path, vary: float, shard: int = 4000
) -> Path:
    """A dataset of ``n`` rendered frames; shard ``i`` drawn from ``SeedSequence(seed, spawn_key=(i,))``, so
    the same seed gives the same bytes."""
    shards = []
    for i, lo in enumerate(range(0, n, shard)):
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,)))
        shards.append(render_frames(template, scene, min(shard, n - lo), rng, vary))
    descriptions = {k: OUTPUTS[k] for k in ("readings", "pressure")}
    return write_shards(out, scene, seed, shards, descriptions)


def _init_weights(spec: str) -> str:
    """A run folder or ``.pt`` path as given; a shipped strip model's name -> its ``.pt`` beside the ``.onnx``."""
    if Path(spec).exists():
        return spec
    from tactile_learn.model_files import shipped_models

    shipped = shipped_models("strips")
    if spec not in shipped or not shipped[spec].with_suffix(".pt").is_file():
        raise ConfigError(
            f"init: {spec!r} is neither a weights file, a run folder nor a shipped strip model with weights"
        )
    return str(shipped[spec].with_suffix(".pt"))


def learn_object(
    readings: np.ndarray,
    scene: Scene,
    out: Path,
    config: LearnConfig | None = None,
    tomography: TomographyConfig | None = None,
    command: str | None = None,
    log: Callable[[str], None] = print,
    readings_path: str | None = None,
) -> dict[str, Any]:
    """Fit, render, fine-tune and export in ``out`` (new or empty); returns what ``object.json`` records
    (with ``readings_path``, where ``readings`` came from and their checksum: a known-objects router is
    fitted on them later)."""
    from tactile_learn.export import export
    from tactile_learn.train import TrainConfig, train

    cfg = config or LearnConfig()
    tomo = tomography or TomographyConfig(seed=cfg.seed)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(f"--out: {out} exists and is not empty; a learned object is written to a new folder")
    init = _init_weights(cfg.init)
    frames, counts = readable_object_frames(readings, scene.sensor, min_frames=cfg.min_frames)
    frames = frames[: cfg.frames]
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    log(f"fitting the object's template to {len(frames)} frames")
    template = fit_template(frames, scene.sensor, scene.digest, tomo, log=log)
    template.save(out / "template.npz")
    fit_seconds = time.perf_counter() - start
    log(f"rendering {cfg.n_train} training and {cfg.n_val} validation frames")
    seeds = np.random.SeedSequence(cfg.seed).generate_state(2)
    write_rendered(template, scene, cfg.n_train, int(seeds[0]), out / RENDERED_TRAIN, cfg.vary)
    write_rendered(template, scene, cfg.n_val, int(seeds[1]), out / RENDERED_VAL, cfg.vary)
    log(f"fine-tuning {cfg.init} for {cfg.epochs} epochs")
    run = out / "run"
    trained = train(
        TrainConfig(
            task="strips",
            data=str(out / RENDERED_TRAIN),
            val=str(out / RENDERED_VAL),
            out=str(run),
            epochs=cfg.epochs,
            lr=cfg.lr,
            patience=cfg.epochs,
            init=init,
            seed=cfg.seed,
            threads=cfg.threads,
        ),
        progress=False,
    )
    card = export(run, out / "specialist.onnx", name=out.name or "specialist")
    record = {
        "kind": OBJECT_KIND,
        "frames": counts | {"fitted": len(frames)},
        "readings": None if readings_path is None else readings_record(readings_path, readings),
        "fit": {
            "tomography": asdict(tomo),
            "residual_median": float(np.median(template.residual)),
            "residual_p90": float(np.percentile(template.residual, 90)),
            "seconds": round(fit_seconds, 1),
        },
        "render": {"n_train": cfg.n_train, "n_val": cfg.n_val, "vary": cfg.vary, "seeds": [int(s) for s in seeds]},
        "training": {"init": cfg.init, "epochs": cfg.epochs, "lr": cfg.lr, "best_epoch": trained.get("best_epoch")},
        "specialist": "specialist.onnx",
        "validation_r": card["metrics"]["validation"].get("pearson_r_mean"),
        "scene": scene.name,
        "scene_digest": scene.digest,
        "command": command,
        "seconds": round(time.perf_counter() - start, 1),
    }
    atomic_write_json(out / OBJECT_FILE, record)
    return record
