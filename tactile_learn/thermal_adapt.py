"""From a user's labelled recordings to a classifier of their sensor: calibrate -> generate -> train ->
export (a workflow above the tasks; nothing below imports it).

:func:`adapt` (numpy, scipy and torch): calibrate (:mod:`tactile_learn.calibration.thermal_scene`),
generate a training and a validation set from the calibrated scene, train a small network, evaluate
it on the labelled real touches themselves (the validation a user can trust: the synthetic set only
shows the network learnt the simulator), export ONNX with a card holding the calibration report, the
classes, the channels and the metrics, and warn when the real-touch accuracy is near chance. Last,
the classifier the user gets (:mod:`tactile_learn.thermal_choice`): per duration, the network, the
calibrated model and the classifiers trained on the labelled touches alone are scored on those
touches and those within one touch of the best vote; the choice goes into the card and the labelled
touches are copied into the folder, so that ``tactile-learn eval --method OUT/`` classifies with it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from synth.errors import ConfigError, DataError
from synth.scene import Scene

# the calibration's names, re-exported from their old home
from tactile_learn.calibration.thermal_scene import (
    CHANNEL_CHOICES,
    OBJECT_SPAN_K,
    RECORD_S,
    WINDOW_S,
    _classes,
    _onset,
    calibrate_recordings,
    scene_from_fit,
    write_scene,
)

__all__ = [
    "CHANNEL_CHOICES",
    "NEAR_CHANCE",
    "OBJECT_SPAN_K",
    "RECORD_S",
    "WINDOW_S",
    "_classes",
    "_onset",
    "adapt",
    "adapt_scene",
    "calibrate_recordings",
    "scene_from_fit",
    "write_scene",
]


#: accuracy on the labelled touches below chance + this is reported as "near chance"
NEAR_CHANCE = 0.15


def adapt(
    data: str | Path,
    out: str | Path,
    *,
    channels: str = "all",
    class_map: dict[str, tuple[str, ...]] | None = None,
    starts: int = 6,
    seed: int = 0,
    **options: Any,
) -> dict[str, Any]:
    """Calibrate, generate, train, validate on the labelled touches, export (module docstring).

    ``out`` receives ``sensor.toml`` (the calibrated scene), ``calibration.json``, ``train/`` and
    ``val/`` (synthetic datasets), ``run/`` (the training run) and ``model.onnx`` + ``model.json``
    (its card). ``options`` go to :func:`adapt_scene`. Returns the card.
    """
    import time

    if channels not in CHANNEL_CHOICES:
        raise ConfigError(f"--channels: {channels!r} is not one of {', '.join(CHANNEL_CHOICES)}")
    folder = Path(out)
    if folder.exists() and any(folder.iterdir()):
        raise DataError(f"{folder} is not empty: adapt writes a fresh folder (choose another --out)")
    started = time.perf_counter()
    scene, report = calibrate_recordings(
        data, CHANNEL_CHOICES[channels], class_map, starts=starts, seed=seed, name=f"adapted_{channels}"
    )
    report["seconds"] = time.perf_counter() - started
    return adapt_scene(scene, report, data, folder, channels=channels, seed=seed, **options)


def adapt_scene(
    scene: Scene,
    report: dict[str, Any],
    data: str | Path,
    out: str | Path,
    *,
    channels: str = "all",
    n_train: int = 16000,
    n_val: int = 1000,
    epochs: int = 12,
    size: str = "tiny",
    seed: int = 0,
    threads: int = 1,
    workers: int = 1,
    progress: bool | None = None,
) -> dict[str, Any]:
    """Everything after the calibration (``scene``, ``report``): the classifier reads ``channels``."""
    import dataclasses
    import time

    from synth.config import replace
    from synth.dataset import generate
    from synth.io import atomic_write_json
    from tactile_learn.export import export
    from tactile_learn.runtime import OnnxEstimator, card_path
    from tactile_learn.tasks.thermal import ThermalTask
    from tactile_learn.thermal_choice import write_choice
    from tactile_learn.train import TrainConfig, train

    started = time.perf_counter()
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    config = replace(scene.sensor, "channels", list(CHANNEL_CHOICES[channels]))
    scene = dataclasses.replace(scene, sensor=config, name=f"adapted_{channels}")
    write_scene(scene, folder / "sensor.toml", report)
    atomic_write_json(folder / "calibration.json", report)
    timings: dict[str, float] = {"calibrate_s": float(report.get("seconds", report["solver"]["seconds"]))}
    mark = time.perf_counter()
    generate(scene, n_train, seed * 2 + 1, folder / "train", workers=workers, shard_size=4096)
    generate(scene, n_val, seed * 2 + 2, folder / "val", workers=workers, shard_size=4096)
    timings["generate_s"] = time.perf_counter() - mark
    mark = time.perf_counter()
    # the labelled real touches are the validation set: the epoch kept is the one that classifies
    # the user's own touches best (a synthetic validation set only shows the simulator was learnt)
    train_config = TrainConfig(
        task="thermal",
        data=str(folder / "train"),
        val=str(data),
        out=str(folder / "run"),
        size=size,
        epochs=epochs,
        seed=seed,
        threads=threads,
        patience=epochs,
    )
    train(train_config, progress=progress)
    timings["train_s"] = time.perf_counter() - mark
    mark = time.perf_counter()
    card = export(folder / "run", folder / "model.onnx", name=f"adapted_{channels}", test=folder / "val")
    task = ThermalTask()
    network = OnnxEstimator(folder / "model.onnx").prepare()
    real = task.evaluate(network, task.load_eval_data(data, scene))
    timings["export_s"] = time.perf_counter() - mark
    mark = time.perf_counter()
    # what the user classifies with: the candidates the labelled touches support (thermal_choice)
    classifier = write_choice(network, data, folder, scene)
    timings["choose_s"] = time.perf_counter() - mark
    k = len(scene.sensor.class_names)
    chance = 1.0 / k
    warnings = []
    if not real["accuracy"] >= chance + NEAR_CHANCE:
        warnings.append(
            f"the network's accuracy on the labelled touches is {real['accuracy']:.2f}, near chance ({chance:.2f}): "
            "the calibrated simulator does not explain these touches well enough (see calibration.json: residual, "
            "parameters at a bound); the classifier adapt chose leans on the few-shot classifiers where they do "
            f"better (card: classifier; tactile-learn eval --task thermal --method {folder} --data YOUR_TOUCHES)"
        )
    longest = max(classifier["by_duration"], key=float)  # the longest contact the labelled records reach
    longest_s = float(longest)
    best = max(classifier["by_duration"][longest]["scores"].values())
    if not best >= chance + NEAR_CHANCE:
        warnings.append(
            f"no candidate classifies the labelled touches better than {best:.2f} at {longest_s:g} s of contact "
            f"(chance {chance:.2f}): label more touches, check the labels and the onsets"
        )
    if report["residual"]["rms_sigma"] > 3.0:
        warnings.append(
            f"the calibration leaves {report['residual']['rms_k'] * 1e3:.1f} mK RMS "
            f"({report['residual']['rms_sigma']:.1f} noise sigma): the model does not explain every detail"
        )
    timings["total_s"] = timings["calibrate_s"] + time.perf_counter() - started
    card["classes"] = list(scene.sensor.class_names)
    card["channels"] = list(scene.sensor.channels)
    card["calibration"] = report
    card["metrics"]["labelled_touches"] = {"data": Path(data).name, "values": real}
    card["classifier"] = classifier
    card["adapt"] = {"timings_s": timings, "n_train": n_train, "n_val": n_val, "epochs": epochs, "size": size}
    card["warnings"] = warnings
    atomic_write_json(card_path(folder / "model.onnx"), card)
    return card
