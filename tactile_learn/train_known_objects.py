"""Build a known-objects bundle (:mod:`tactile_learn.known_objects`): fit its router and choose its threshold.

The router is :func:`tactile_learn.train_router.fit_mlp` on the readings' features
(:func:`tactile_learn.prior_route.route_features`), one class per known object (frames of the dataset its
specialist was trained on) and one more, *other*: frames of objects that are not known. The threshold
``accept`` is chosen on frames no router trained on: the lowest probability (at least 0.5) that routes at
most ``false_share`` of them to a specialist. By default they are the last ``val_frames`` frames of every
second *other* dataset, whose objects the router never trains on (a deployment meets objects it never saw;
docs/strips.md measured that a threshold chosen on unseen frames of seen objects promises too much); with
``calibrate_on="frames"`` the last ``val_frames`` of every *other* dataset, the router trained on all. What it cost is
measured on held-out frames of the known objects too (the last ``val_frames`` of each object's dataset) and
recorded in the bundle.

Frames of objects outside the known set and outside *other* are what the threshold cannot promise anything
about: docs/strips.md ("Known objects among unknown ones") measures how many of an unseen round's frames a
router sends to a specialist, and what that costs them.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from synth.dataset import load_arrays
from synth.errors import ConfigError
from synth.io import atomic_write_json, sha256_file
from tactile_learn.known_objects import BUNDLE_FILE, BUNDLE_KIND, DEFAULT, ObjectRouter
from tactile_learn.prior_route import PriorRoute, route_features
from tactile_learn.train_router import fit_mlp, router_arrays

__all__ = [
    "CALIBRATIONS",
    "OFFSET",
    "SHARE_SCALE",
    "accept_for",
    "build_bundle",
    "fit_classes",
    "other_frames_for",
    "split_frames",
]

#: the router's features: the strip readings above the readout's offset, as shares of their total x 16
OFFSET, SHARE_SCALE = 0.3, 16.0
#: fewer frames of a known object than this (or than asked for, if fewer) is no class to fit
MIN_OBJECT_FRAMES = 100


def _readings(folder: Path) -> np.ndarray:
    return np.asarray(load_arrays(folder, ["readings"])["readings"], dtype=np.float32)


def split_frames(folders: list[Path], frames: int, val_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """The first ``frames`` frames over ``folders`` (split evenly) to train on, and the last ``val_frames`` of
    each folder held out; refuses a folder too small for both without overlap."""
    if not folders:
        raise ConfigError("no datasets given")
    each = -(-frames // len(folders))
    train, held = [], []
    for folder in folders:
        readings = _readings(folder)
        if len(readings) < each + val_frames:
            raise ConfigError(
                f"{folder}: {len(readings)} frames, fewer than {each} to train on + {val_frames} held out"
            )
        train.append(readings[:each])
        held.append(readings[len(readings) - val_frames :])
    return np.concatenate(train)[:frames], np.concatenate(held)


#: where the threshold is chosen: on held-out frames of the --other datasets' objects ("frames"), or on whole
#: --other datasets the router never trains on ("datasets": objects it never saw, as a deployment meets them)
CALIBRATIONS = ("datasets", "frames")


def other_frames_for(
    other: list[Path], frames: int, val_frames: int, calibrate_on: str
) -> tuple[np.ndarray, np.ndarray]:
    """The *other* class's training frames and the frames the threshold is chosen on. ``"frames"``: the first
    ``frames`` over all of ``other`` and the last ``val_frames`` of each; ``"datasets"``: the first ``frames``
    over every other dataset (the 1st, 3rd, ...) and the last ``val_frames`` of each of the rest."""
    if calibrate_on not in CALIBRATIONS:
        raise ConfigError(f"calibrate on {calibrate_on!r}: expected one of {', '.join(CALIBRATIONS)}")
    if calibrate_on == "frames":
        return split_frames(other, frames, val_frames)
    if len(other) < 2:
        raise ConfigError(
            "calibrating on held-out datasets needs at least two --other datasets (or calibrate on frames)"
        )
    train, _ = split_frames(other[0::2], frames, 0)
    _, held = split_frames(other[1::2], 0, val_frames)
    return train, held


def accept_for(top_known: np.ndarray, false_share: float) -> float:
    """The lowest threshold, at least 0.5, that routes at most ``false_share`` of frames whose best known
    object's probability is ``top_known`` (a frame is routed when it exceeds the threshold)."""
    if not 0.0 <= false_share < 1.0:
        raise ConfigError(f"false share must be in [0, 1), got {false_share}")
    return max(0.5, float(np.quantile(top_known, 1.0 - false_share, method="higher")))


def _specialist_data(model: Path) -> Path:
    card_file = model.with_suffix(".json")
    try:
        card = json.loads(card_file.read_text())
        return Path(card["training"]["data"]["path"])
    except (OSError, ValueError, KeyError, TypeError):
        raise ConfigError(
            f"{card_file}: its card names no single training dataset; give the object's frames with --data"
        ) from None


def fit_classes(classes: list[np.ndarray], seed: int) -> tuple[Any, np.ndarray, np.ndarray]:
    """:func:`~tactile_learn.train_router.fit_mlp` telling the readings of each array in ``classes`` (label: its
    index) apart, on the features :class:`ObjectRouter` computes: the net (torch) and the features' mean and
    scale it normalises by."""
    import torch

    x = np.concatenate([route_features(c, OFFSET, SHARE_SCALE) for c in classes]).astype(np.float32)
    labels = np.concatenate([np.full(len(c), k) for k, c in enumerate(classes)])
    mean, std = x.mean(axis=0), x.std(axis=0) + 1e-6
    net = fit_mlp(
        torch.from_numpy((x - mean) / std),
        torch.from_numpy(labels),
        np.arange(len(x)),
        np.random.default_rng(seed),
        seed,
        len(classes),
        torch.nn.functional.cross_entropy,
    )
    return net, mean, std


def fit_router(classes: list[np.ndarray], seed: int) -> dict[str, np.ndarray]:
    """The router's arrays (:func:`fit_classes`' net and normalisation, as a router file holds them)."""
    return router_arrays(*fit_classes(classes, seed))


def held_out_routing(
    router: ObjectRouter, accept: float, known_val: list[np.ndarray], other_val: np.ndarray
) -> dict[str, Any]:
    """What the threshold does to held-out frames: the share of *other*'s sent to a specialist, and per known
    object the shares sent to its own specialist and to the default."""
    known = len(router.objects)
    validation: dict[str, Any] = {"other_routed_share": float(np.mean(router.choose(other_val, accept) < known))}
    validation["objects"] = {}
    for k, (name, held) in enumerate(zip(router.objects, known_val, strict=True)):
        choice = router.choose(held, accept)
        validation["objects"][name] = {
            "to_own_specialist": float(np.mean(choice == k)),
            "to_default": float(np.mean(choice == known)),
        }
    return validation


def build_bundle(
    objects: dict[str, Path],
    other: list[Path],
    out: Path,
    *,
    default: str = "strips16",
    data: dict[str, Path] | None = None,
    train_frames: int = 5000,
    other_frames: int = 60000,
    val_frames: int = 200,
    false_share: float = 0.01,
    calibrate_on: str = "datasets",
    seed: int = 0,
    command: str = "",
    log: Callable[[str], None] = print,
) -> dict[str, Any]:
    """Fit the router of ``objects`` (name -> specialist ``.onnx`` with its card) against ``other`` datasets,
    choose its threshold, and write the bundle to the new folder ``out``; returns ``bundle.json``'s content.
    Each object's frames are ``data[name]``, else the dataset its specialist's card names: at most ``train_frames``
    of them (fewer where it holds fewer; ``trained_on`` records how many)."""
    if len(objects) < 1 or DEFAULT in objects:
        raise ConfigError(f"a bundle needs at least one object, none named {DEFAULT!r}")
    if min(train_frames, other_frames, val_frames) < 1:
        raise ConfigError("train, other and held-out frame counts must be at least 1")
    if (out / BUNDLE_FILE).exists():
        raise ConfigError(f"{out / BUNDLE_FILE} exists: choose another folder (a bundle is never overwritten)")
    for name, model in objects.items():
        if not model.is_file() or not model.with_suffix(".json").is_file():
            raise ConfigError(f"object {name!r}: {model} and its card {model.with_suffix('.json')} must both exist")
    # every input read and checked before anything is written
    known_train, known_val, trained_on = [], [], {}
    for name, model in objects.items():
        folder = (data or {}).get(name) or _specialist_data(model)
        readings = _readings(folder)
        # at most train_frames: a learned object's own recording may hold fewer (the bundle records how many)
        take, least = min(train_frames, len(readings) - val_frames), min(train_frames, MIN_OBJECT_FRAMES)
        if take < least:
            raise ConfigError(
                f"object {name!r}: {folder} holds {len(readings)} frames; at least {least} to train on "
                f"+ {val_frames} held out are needed"
            )
        known_train.append(readings[:take])
        known_val.append(readings[len(readings) - val_frames :])
        trained_on[name] = {"data": str(folder), "frames": int(take)}
    other_train, other_val = other_frames_for(other, other_frames, val_frames, calibrate_on)
    log(f"fitting the router: {len(objects)} objects + other, {sum(map(len, known_train)) + len(other_train)} frames")
    arrays = fit_router([*known_train, other_train], seed)
    router = ObjectRouter(arrays, OFFSET, SHARE_SCALE, tuple(objects))
    accept = accept_for(router.probabilities(other_val)[:, : len(objects)].max(axis=1), false_share)
    if not accept < 1.0:  # (float32 probabilities saturate at 1): no threshold a bundle may hold keeps the promise
        raise ConfigError(
            f"the router gives more than {false_share:.2%} of the --other datasets' held-out frames a known object "
            "with probability 1: it cannot tell them from the known objects (raise --false-share, or give --other "
            "frames of more kinds)"
        )
    validation = held_out_routing(router, accept, known_val, other_val)
    out.mkdir(parents=True, exist_ok=True)
    files = {}
    for name, model in objects.items():
        shutil.copyfile(model, out / f"{name}.onnx")
        shutil.copyfile(model.with_suffix(".json"), out / f"{name}.json")
        files[name] = f"{name}.onnx"
    PriorRoute.save(out / "router.npz", arrays)
    bundle = {
        "format": 1,
        "kind": BUNDLE_KIND,
        "task": "strips",
        "default": default,
        "objects": files,
        "router": "router.npz",
        "router_sha256": sha256_file(out / "router.npz"),
        "offset": OFFSET,
        "share_scale": SHARE_SCALE,
        "accept": accept,
        "false_share": false_share,
        "calibrate_on": calibrate_on,
        "frames": {"train_per_object": train_frames, "other": other_frames, "held_out_per_dataset": val_frames},
        "trained_on": trained_on,
        "other": [str(p) for p in other],
        "seed": seed,
        "validation": validation,
        "command": command,
    }
    atomic_write_json(out / BUNDLE_FILE, bundle)  # last, whole: a bundle never names files not yet written
    return bundle
