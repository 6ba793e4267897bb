"""The thermal fingertip task (issues 4 and 11): temperature curves -> material or class.

Input ``readings`` (B, W): one thermistor's temperatures (degC) over the last ``W = window_s * fs``
samples, ending "now"; the contact onset is somewhere inside (the 4 x 4 array is classified pixel
by pixel: every pixel's curve is one row). A scene whose ``channels`` also name the passive
thermistor takes (B, 2, W): heated, then passive, over the same samples. Output
``probabilities`` (B, K + 1): the scene's K classes (its user classes, e.g. metal and wood, else
its materials), then ``none`` (the pixel touches nothing).

Views by contact duration. A generated touch keeps its whole record (``readings`` (P, R), and
``passive``) and its onset; the view at duration ``d`` is the window that ends at the last sample
with ``t <= onset + d`` (padded on the left with the record's first sample if the record starts
later than the window); a view exists while the record, and the contact when its release is known,
lasts. :meth:`ThermalTask.evaluate` predicts every view ``d`` in :data:`DURATIONS_S` (or the
``durations`` it is given):

- ``accuracy``: class accuracy over pixels in contact, pooled over the views;
- ``accuracy_by_duration``, ``family_accuracy_by_duration``, ``contact_accuracy_by_duration``
  (keys ``"0.25"``, ``"0.5"``, ``"1.0"``, ``"2.0"``, ``"4.0"``); family = metal, stone/glass,
  polymer, wood, foam; contact accuracy = touching vs ``none`` over every pixel;
- ``confusion_pairs``: the most frequent (true, predicted) errors pooled over the views, with their
  nominal effusivities;
- ``per_material_accuracy``: per class at 1 s;
- ``by_group`` (with ``group_by``): all of the above per value of a touches.csv column.

The oracle (the physics fit given each pixel's true sensor parameters) is not an estimator (it
needs the truth): :func:`oracle_accuracy_by_duration` computes ``oracle_accuracy_by_duration`` for
the same data; ``eval``/``bench`` call it and add the key beside the method's metrics.

Evaluation data: a generated dataset folder, an ``.npz`` (``readings`` (B, R) or (B, P, R) in
degC at the scene's rate, ``passive`` alike when the scene reads it, labels ``latent_material``
(int index, -1 = none) or ``material`` (names), optional ``latent_onset_s``/``onset_s``), or a
recording directory (:mod:`tactile_learn.thermal_recordings`: the onset from touches.csv, else the
force column's half-plateau crossing, else the heated curve's departure).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from synth.config import dumps_toml
from synth.dataset import Dataset, load_arrays
from synth.errors import ConfigError, DataError
from synth.io import atomic_write_text
from synth.materials import Material
from synth.scene import Scene, load_scene, parse_scene
from synth.sensors.thermal import ThermalConfig
from tactile_learn.estimators.base import Estimator, prepared
from tactile_learn.tasks.base import EvalData, Task
from tactile_learn.thermal_signal import onset_seconds, windows
from tactile_learn.validation.common import InputCheck
from tactile_learn.validation.thermal import thermal_check, thermal_input_shape

if TYPE_CHECKING:
    import torch

__all__ = [
    "DURATIONS_S",
    "Classes",
    "ThermalTask",
    "channel_keys",
    "class_names",
    "classes_of",
    "labels_from_materials",
    "oracle_accuracy_by_duration",
    "thermal_metrics",
    "view",
    "windows",
]

#: contact durations (s) of the evaluation views (``eval --durations`` chooses others)
DURATIONS_S: tuple[float, ...] = (0.25, 0.5, 1.0, 2.0, 4.0)
NONE = "none"
#: training windows end this long after onset at least / before the window's start at most
_TRAIN_MIN_S = 0.1
_TRAIN_BASE_S = 0.2
#: pixels drawn per touch in a training batch
_TRAIN_PIXELS = 4
#: a real record starts this long (uniform, s) before its contact; training cuts windows alike
_RECORD_LEAD_S = (0.3, 3.0)


def _config(scene: Scene) -> ThermalConfig:
    if not isinstance(scene.sensor, ThermalConfig):
        raise DataError(f"scene {scene.name!r} is not a thermal scene (task {scene.task!r})")
    return scene.sensor


@dataclass(frozen=True)
class Classes:
    """What a scene classifies: names, each class's family index (-1: mixed) and effusivity."""

    names: tuple[str, ...]
    families: np.ndarray
    effusivity: np.ndarray

    def __len__(self) -> int:
        return len(self.names)


def classes_of(source: ThermalConfig | Sequence[Material]) -> Classes:
    """The classes of a scene's config (its user classes, else its materials) or of materials."""
    if isinstance(source, ThermalConfig):
        mats, of = source.material_list, source.class_of_material
        names = source.class_names
    else:
        mats, of = tuple(source), np.arange(len(source))
        names = tuple(m.name for m in mats)
    families, eff = [], []
    for k in range(len(names)):
        members = [m for m, c in zip(mats, of, strict=True) if c == k]
        fam = {m.family_index for m in members}
        families.append(fam.pop() if len(fam) == 1 else -1)
        eff.append(float(np.exp(np.mean([np.log(m.effusivity) for m in members]))))
    return Classes(names, np.array(families), np.array(eff))


def recording_labels(config: ThermalConfig) -> dict[str, Any]:
    """How :func:`~tactile_learn.thermal_recordings.read_recordings` reads labels for a scene:
    against its classes (by name) or its materials."""
    if config.objects.classes:
        names = config.class_names
        of = config.class_of_material
        mats = config.material_list
        return {
            "classes": {n: tuple(m.name for m, c in zip(mats, of, strict=True) if c == k) for k, n in enumerate(names)}
        }
    return {"materials": [m.name for m in config.material_list]}


def class_names(scene: Scene) -> tuple[str, ...]:
    """The prediction's classes: the scene's classes (or materials), then ``none``."""
    return (*_config(scene).class_names, NONE)


def labels_from_materials(
    material_index: np.ndarray, n_materials: int, config: ThermalConfig | None = None
) -> np.ndarray:
    """Class labels (int64): the class of the material index (``config``'s classes; without a
    config the material itself), ``none`` where it is -1."""
    idx = np.asarray(material_index).astype(np.int64)
    if config is None:
        return np.where(idx < 0, n_materials, idx)
    of = config.class_of_material
    return np.where(idx < 0, len(config.class_names), of[np.clip(idx, 0, len(of) - 1)])


def channel_keys(config: ThermalConfig) -> tuple[str, ...]:
    """EvalData keys of the records of the scene's input channels (heated first)."""
    return tuple("record" if c == "heated" else f"record_{c}" for c in config.channels)


def view(data: EvalData, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The view of ``data`` at contact duration ``duration_s``: windows (N, W) (one channel) or
    (N, C, W) (several), and a mask of the rows whose record (and contact, when its release is
    known) reaches ``onset + duration_s``."""
    cfg = _config(data.scene)
    fs = cfg.readout.sampling_hz
    length, onset = data.extra["length"], data.extra["onset_s"]
    end_s = np.floor((onset.astype(np.float64) + duration_s) * fs + 1e-9) + 1
    end = np.clip(end_s, 0, length + 1).astype(np.int64)  # clipped first: a far-off onset does not overflow
    valid = end <= length
    if "release_s" in data.extra:  # a simulated touch: the view must end before the release
        valid &= onset + duration_s <= data.extra["release_s"] + 1e-9
    ends = np.minimum(end, length)
    parts = [windows(data.extra[key], length, ends, cfg.window_samples) for key in channel_keys(cfg)]
    return (parts[0] if len(parts) == 1 else np.stack(parts, axis=1)), valid


def thermal_metrics(pred: np.ndarray, labels: np.ndarray, materials: Sequence[Material] | Classes) -> dict[str, Any]:
    """Accuracy (class, over pixels in contact), family and contact accuracy, per-class accuracy
    and the confusion counts of predictions ``pred`` (B, K + 1) against ``labels`` (B,)."""
    classes = materials if isinstance(materials, Classes) else classes_of(materials)
    k = len(classes)
    guess = np.asarray(pred).argmax(axis=1) if len(pred) else np.zeros(0, dtype=np.int64)
    labels = np.asarray(labels).astype(np.int64)
    family = np.concatenate([classes.families, [-2]])
    contact = labels < k
    n = int(contact.sum())
    right = guess[contact] == labels[contact]
    out: dict[str, Any] = {
        "accuracy": float(right.mean()) if n else float("nan"),
        "family_accuracy": float((family[guess[contact]] == family[labels[contact]]).mean()) if n else float("nan"),
        "contact_accuracy": float(((guess < k) == contact).mean()) if len(labels) else float("nan"),
        "n_contact": n,
        "n_none": int((~contact).sum()),
    }
    per = {}
    for i, name in enumerate(classes.names):
        sel = labels == i
        if sel.any():
            per[name] = float((guess[sel] == i).mean())
    out["per_material_accuracy"] = per
    counts = np.zeros((k + 1, k + 1), dtype=np.int64)
    np.add.at(counts, (labels, guess), 1)
    out["confusion"] = counts
    return out


def _confusion_pairs(
    counts: np.ndarray, materials: Sequence[Material] | Classes, top: int = 12
) -> list[dict[str, Any]]:
    classes = materials if isinstance(materials, Classes) else classes_of(materials)
    names = [*classes.names, NONE]
    eff = [*classes.effusivity.tolist(), 0.0]
    totals = counts.sum(axis=1)
    pairs: list[dict[str, Any]] = []
    for i in range(len(classes)):
        for j in range(len(names)):
            if i != j and counts[i, j] > 0:
                pairs.append(
                    {
                        "true": names[i],
                        "predicted": names[j],
                        "count": int(counts[i, j]),
                        "rate": float(counts[i, j] / totals[i]),  # totals[i] >= counts[i, j] > 0
                        "effusivity_true": round(eff[i], 1),
                        "effusivity_predicted": round(eff[j], 1),
                    }
                )
    pairs.sort(key=lambda p: -p["count"])
    return pairs[:top]


def _groups(data: EvalData, column: str) -> np.ndarray:
    """The values of ``column`` per row: a touches.csv column of recordings, or a per-pixel array
    of simulated data (``latent_...``); a DataError lists what exists."""
    for key in (f"info:{column}", column, f"latent_{column}"):
        if key in data.extra:
            return np.asarray(data.extra[key]).astype(str)
    known = sorted(k[5:] for k in data.extra if k.startswith("info:")) + sorted(
        k for k in data.extra if k.startswith("latent_")
    )
    raise DataError(f"--group-by: {data.source} has no column {column!r} (available: {', '.join(known) or 'none'})")


def _key(d: float) -> str:
    return f"{d:g}" if d != int(d) else f"{d:.1f}"


class ThermalTask(Task):
    name = "thermal"
    default_scene = "thermal"
    input_key = "readings"
    output_key = "probabilities"
    truth_keys = ("latent_material", "latent_onset_s", "latent_release_s")
    primary_metric = ("accuracy", True)
    net_sizes = ("tiny", "small", "medium", "large")
    default_epochs = 40
    stats_limit = 2000  # whole touches (16 pixels x a full record each): 2,000 are plenty
    bench_samples = 200  # touches: 3,200 pixel curves, each viewed at four contact durations

    def input_shape(self, scene: Scene) -> tuple[int, ...]:
        return thermal_input_shape(_config(scene))

    def train_keys_for(self, scene: Scene) -> tuple[str, ...]:
        extra = tuple(c for c in _config(scene).channels if c != "heated")
        return (*self.train_keys, *extra)

    def output_labels(self, scene: Scene) -> tuple[str, ...]:
        return class_names(scene)

    def input_check(self, scene: Scene) -> InputCheck:
        """:func:`~tactile_learn.validation.thermal.thermal_check`."""
        return thermal_check(_config(scene))

    def fast_bounds(self, scene: Scene) -> tuple[float, float, bool] | None:
        return thermal_check(_config(scene)).bounds()

    def example_inputs(self, arrays: dict[str, np.ndarray], scene: Scene) -> np.ndarray:
        """Estimator inputs from simulated dataset arrays (``readings`` (B, P, R) and the latents):
        every pixel's window at 1 s of contact, (B * P, W). (The generic machinery's probe and
        conformance inputs; ``arrays["readings"]`` itself is a whole record, not an input.)"""
        data = self._from_arrays(arrays, scene, "<arrays>")
        return view(data, 1.0)[0]

    def latency_inputs(self, data: EvalData) -> np.ndarray:
        """One pixel's window at 1 s of contact per frame: what a deployed classifier is fed."""
        return view(data, 1.0)[0]

    def reference_metrics(self, data: EvalData, limit: int | None = None) -> dict[str, Any]:
        """Metrics that do not depend on the method: the oracle's (see
        :func:`oracle_accuracy_by_duration`); empty when ``data`` lacks the sensor's latents."""
        if "latent_heat_capacity_j_m2k" not in data.extra:
            return {}
        return oracle_accuracy_by_duration(data, limit)

    def classical_methods(self) -> dict[str, Callable[[Scene], Estimator]]:
        from tactile_learn.estimators.classical.calibrated_fit import CalibratedFitEstimator
        from tactile_learn.estimators.classical.curve_match import CurveMatchEstimator
        from tactile_learn.estimators.classical.physics_fit import PhysicsFitEstimator

        return {
            "curve_match": prepared(CurveMatchEstimator),
            "physics_fit": prepared(PhysicsFitEstimator),
            "calibrated": prepared(CalibratedFitEstimator),
        }

    # ---- evaluation data -----------------------------------------------------------------------

    def load_eval_data(self, source: str | Path, scene: Scene | None = None) -> EvalData:
        from tactile_learn.thermal_recordings import INDEX

        path = Path(source)
        if path.is_dir() and (path / INDEX).is_file():
            return self._from_recordings(path, scene or load_scene(self.default_scene))
        if path.is_dir():
            dataset = Dataset(path)
            if dataset.scene.task != self.name:
                raise DataError(f"{path}: dataset is for task {dataset.scene.task!r}, not {self.name!r}")
            arrays = dataset.arrays()
            scene = scene or dataset.scene
        else:
            arrays = load_arrays(path)
            scene = scene or load_scene(self.default_scene)
        return self._from_arrays(arrays, scene, str(path))

    def _from_arrays(self, arrays: dict[str, np.ndarray], scene: Scene, source: str) -> EvalData:
        cfg = _config(scene)
        if "readings" not in arrays:
            raise DataError(f"{source}: needs an array 'readings' (B, R) or (B, P, R) of temperatures (degC)")
        readings = np.asarray(arrays["readings"])
        if not np.issubdtype(readings.dtype, np.number) or np.iscomplexobj(readings):
            raise DataError(f"{source}: readings must be real numbers (degC), got dtype {readings.dtype}")
        if readings.ndim == 2:
            readings = readings[:, None, :]
        if readings.ndim != 3 or readings.shape[2] < 2:
            raise DataError(f"{source}: readings have shape {readings.shape}, expected (B, R) or (B, P, R)")
        b, p, r = readings.shape
        k = len(cfg.material_list)

        def per_touch(name: str, values: Any) -> np.ndarray:
            """``values`` as (B, P) (one per pixel) or (B, 1) (one per touch)."""
            arr = np.asarray(values)
            if arr.size == b * p:
                return arr.reshape(b, p)
            if arr.size == b:
                return arr.reshape(b, 1)
            raise DataError(f"{source}: {name} have shape {arr.shape}, readings {readings.shape} need {(b, p)}")

        if "latent_material" in arrays:
            mat = per_touch("labels", arrays["latent_material"])
            integral = mat.dtype.kind in "iu" or (
                mat.dtype.kind == "f" and bool(np.isfinite(mat).all()) and bool((mat == np.round(mat)).all())
            )
            if not integral:
                raise DataError(
                    f"{source}: latent_material must hold integer material indices (-1 = none), got dtype {mat.dtype}"
                )
            mat = mat.astype(np.int64)
            class_level = False
        elif "material" in arrays:
            names = list(cfg.class_names)
            mat_names = [m.name for m in cfg.material_list]
            raw = per_touch("labels", arrays["material"])
            unknown = sorted({str(v) for v in raw.ravel() if str(v) not in (*names, *mat_names, NONE, "")})
            if unknown:
                raise DataError(
                    f"{source}: label(s) {', '.join(unknown)} not in the scene's classes ({', '.join(names)})"
                )

            def to_class(v: str) -> int:
                if v in names:
                    return names.index(v)
                if v in mat_names:
                    return int(cfg.class_of_material[mat_names.index(v)])
                return -1

            mat = np.array([to_class(str(v)) for v in raw.ravel()], dtype=np.int64).reshape(raw.shape)
            class_level = True
        else:
            raise DataError(
                f"{source}: needs labels 'latent_material' (material index, -1 = none) or 'material' (names)"
            )
        if mat.shape != (b, p):
            raise DataError(f"{source}: labels have shape {mat.shape}, readings {readings.shape} need {(b, p)}")
        if not class_level and mat.size and (mat.max() >= k or mat.min() < -1):
            raise DataError(f"{source}: material indices must lie in [-1, {k - 1}] for scene {scene.name!r}")
        records = readings.reshape(b * p, r).astype(np.float32)
        onset_key = next((key for key in ("latent_onset_s", "onset_s") if key in arrays), None)
        if onset_key is not None:
            given = per_touch(onset_key, arrays[onset_key])
            if not np.issubdtype(given.dtype, np.number) or not np.isfinite(given).all():
                raise DataError(f"{source}: {onset_key} must be finite numbers (s from the record's start)")
            onset = np.broadcast_to(given.astype(np.float64), (b, p)).ravel()
        else:
            onset = self._detect_onsets(records, cfg)
        extra: dict[str, np.ndarray] = {
            "record": records,
            "length": np.full(b * p, r, dtype=np.int64),
            "onset_s": onset.astype(np.float64),
            "touch": np.repeat(np.arange(b), p),
            "pixel": np.tile(np.arange(p), b),
        }
        for channel in cfg.channels[1:]:
            if channel not in arrays:
                raise DataError(
                    f"{source}: scene {scene.name!r} reads the {channel} channel: needs an array {channel!r}"
                )
            other = np.asarray(arrays[channel])
            if other.size != b * p * r:
                raise DataError(f"{source}: {channel} has shape {other.shape}, readings {readings.shape}")
            extra[f"record_{channel}"] = other.reshape(b * p, r).astype(np.float32)
        for key, value in arrays.items():
            if key.startswith("latent_") and np.asarray(value).shape[:2] == (b, p):
                extra[key] = np.asarray(value).reshape(b * p, *np.asarray(value).shape[2:])
        if "latent_release_s" in extra:
            extra["release_s"] = extra["latent_release_s"].astype(np.float64)
        flat = mat.ravel()
        labels = np.where(flat < 0, len(cfg.class_names), flat) if class_level else labels_from_materials(flat, k, cfg)
        data = EvalData(
            inputs=np.zeros((b * p, 0), np.float32), truth={"label": labels}, scene=scene, extra=extra, source=source
        )
        data.inputs = view(data, 2.0)[0]
        return data

    def _detect_onsets(self, records: np.ndarray, cfg: ThermalConfig) -> np.ndarray:
        return onset_seconds(records, cfg.readout.sampling_hz, cfg.readout.adc_step_k)[0]

    def _from_recordings(self, path: Path, scene: Scene) -> EvalData:
        from tactile_learn.thermal_recordings import read_recordings, resample_channel
        from tactile_learn.thermal_signal import press_onset, press_profile

        cfg = _config(scene)
        fs = cfg.readout.sampling_hz
        touches = read_recordings(path, **recording_labels(cfg))
        channels = [("record", "temperature_c")] + [(f"record_{c}", f"{c}_c") for c in cfg.channels[1:]]
        for t in touches:
            for _, column in channels[1:]:
                if getattr(t, column) is None:
                    raise DataError(
                        f"{path / t.file}: scene {scene.name!r} reads {column}: the file has no such column"
                    )
        series = {key: [resample_channel(t, column, fs) for t in touches] for key, column in channels}
        lengths = np.array([len(v) for v in series["record"]], dtype=np.int64)
        r = int(lengths.max())
        extra: dict[str, np.ndarray] = {}
        for key, values in series.items():
            records = np.empty((len(touches), r), dtype=np.float32)
            for i, v in enumerate(values):
                records[i, : len(v)] = v
                records[i, len(v) :] = v[-1]
            extra[key] = records
        detected = self._detect_onsets(extra["record"], cfg)
        # the press (force / its plateau) on the same grid, for methods that time the contact by it
        press = np.zeros((len(touches), r), dtype=np.float32)
        has_press = np.zeros(len(touches), dtype=bool)
        for i, t in enumerate(touches):
            profile = press_profile(t.time_s, t.force) if t.force is not None else None
            if profile is not None:
                values = np.interp(t.time_s[0] + np.arange(lengths[i]) / fs, t.time_s, profile)
                press[i, : len(values)] = values
                press[i, len(values) :] = values[-1]
                has_press[i] = True
        extra.update(press=press, has_press=has_press)
        onset = np.empty(len(touches))
        source = np.empty(len(touches), dtype=object)
        for i, t in enumerate(touches):
            t0 = float(t.time_s[0])
            pressed = press_onset(t.time_s, t.force) if t.force is not None else None
            if t.onset_s is not None:
                onset[i], source[i] = t.onset_s - t0, "given"
            elif pressed is not None:
                onset[i], source[i] = pressed - t0, "force"
            else:
                onset[i], source[i] = detected[i], "curve"
        names = list(cfg.class_names)
        labels = np.array([names.index(t.material) if t.material else -2 for t in touches])
        extra.update(
            length=lengths,
            onset_s=onset,
            onset_from=source,
            labelled=labels >= 0,
            touch=np.arange(len(touches)),
            pixel=np.zeros(len(touches), dtype=np.int64),
            file=np.array([t.file for t in touches], dtype=object),
        )
        for column in sorted({k for t in touches for k in t.info}):
            extra[f"info:{column}"] = np.array([t.info.get(column, "") for t in touches], dtype=object)
        if any(t.info.get("release_s") for t in touches):  # views must end before a release
            extra["release_s"] = np.array(
                [
                    float(t.info["release_s"]) - float(t.time_s[0]) if t.info.get("release_s") else np.inf
                    for t in touches
                ]
            )
        data = EvalData(
            inputs=np.zeros((len(touches), 0), np.float32),
            truth={"label": np.where(labels >= 0, labels, len(names))},
            scene=scene,
            extra=extra,
            source=str(path),
        )
        data.inputs = view(data, 2.0)[0]
        # a record shorter than onset + 2 s is classified on what it has (its end)
        return data

    # ---- metrics -------------------------------------------------------------------------------

    def metrics(self, pred: np.ndarray, data: EvalData) -> dict[str, Any]:
        classes = classes_of(_config(data.scene))
        keep = data.extra.get("labelled", np.ones(len(data), dtype=bool))
        out = thermal_metrics(np.asarray(pred)[keep], data.truth["label"][keep], classes)
        out["confusion_pairs"] = _confusion_pairs(out.pop("confusion"), classes)
        return out

    def evaluate(
        self,
        estimator: Estimator,
        data: EvalData,
        durations: Sequence[float] | None = None,
        group_by: str | None = None,
    ) -> dict[str, Any]:
        """Metrics of ``estimator`` on every duration view (see the module docstring); with
        ``group_by`` (a column of a recording's ``touches.csv``, or a latent of simulated data) the
        same metrics per value of that column under ``by_group``. The estimator (a classifier: its
        ``predict_proba`` is evaluated) is prepared here if it is not yet."""
        proba = estimator.prepare().predict_proba  # type: ignore[attr-defined]  # thermal methods all classify
        if "record" not in data.extra:
            return self.metrics(proba(data.inputs), data)
        return self.evaluate_by_duration(lambda d, x, rows: proba(x), data, durations, group_by)

    def evaluate_by_duration(
        self,
        predict: Callable[[float, np.ndarray, np.ndarray], np.ndarray],
        data: EvalData,
        durations: Sequence[float] | None = None,
        group_by: str | None = None,
    ) -> dict[str, Any]:
        """:meth:`evaluate` for any ``predict(duration_s, windows, rows)`` giving (n, K + 1) scores
        of the touches ``rows`` of ``data`` (their ``windows`` of that duration): a method that
        reads more than the windows (e.g. the force record) or has one model per duration."""
        durations = tuple(DURATIONS_S if durations is None else durations)
        groups = _groups(data, group_by) if group_by else None
        keep_all = data.extra.get("labelled", np.ones(len(data), dtype=bool))
        preds: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for d in durations:
            x, valid = view(data, d)
            keep = valid & keep_all
            if keep.any():
                rows = np.flatnonzero(keep)
                preds[_key(d)] = (rows, predict(d, x[keep], rows))
        result = self._summary(data, preds, np.ones(len(data), dtype=bool))
        if groups is not None:
            result["by_group"] = {
                str(value): {"n_touches": int((groups == value).sum()), **self._summary(data, preds, groups == value)}
                for value in sorted(set(groups.tolist()))
            }
        return result

    def _summary(
        self, data: EvalData, preds: dict[str, tuple[np.ndarray, np.ndarray]], rows: np.ndarray
    ) -> dict[str, Any]:
        classes = classes_of(_config(data.scene))
        k = len(classes)
        by: dict[str, dict[str, Any]] = {}
        total = np.zeros((k + 1, k + 1), dtype=np.int64)
        for d, (index, pred) in preds.items():
            sel = rows[index]
            if not sel.any():
                continue
            m = thermal_metrics(pred[sel], data.truth["label"][index[sel]], classes)
            total += m.pop("confusion")
            by[d] = m
        right = np.trace(total[:k, :k])
        n_contact = total[:k].sum()
        result: dict[str, Any] = {
            "accuracy": float(right / n_contact) if n_contact else float("nan"),
            "accuracy_by_duration": {d: m["accuracy"] for d, m in by.items()},
            "family_accuracy_by_duration": {d: m["family_accuracy"] for d, m in by.items()},
            "contact_accuracy_by_duration": {d: m["contact_accuracy"] for d, m in by.items()},
            "n_contact_by_duration": {d: m["n_contact"] for d, m in by.items()},
            "confusion_pairs": _confusion_pairs(total, classes),
        }
        if "1.0" in by:
            result["per_material_accuracy"] = by["1.0"]["per_material_accuracy"]
        return result

    # ---- calibration ---------------------------------------------------------------------------

    def calibrate(
        self,
        source: str | Path,
        out: str | Path,
        scene: Scene,
        channels: str | None = None,
        class_map: dict[str, tuple[str, ...]] | None = None,
    ) -> dict[str, Any]:
        """Fit the user's sensor from labelled recordings; write a scene TOML for ``generate``.

        Recordings of a real fingertip (a ``passive_c`` or ``force`` column, labels that are
        families or classes, a real-sensor scene, or ``channels`` given) get the real-sensor model
        (:func:`tactile_learn.calibration.thermal_scene.calibrate_recordings`: lags, heater, drift, contact
        build-up, passive channel; the report goes to ``out`` with the suffix ``.json``); plain
        single-material recordings of a seed-like sensor get the seed's model
        (:func:`~tactile_learn.calibration.thermal_seed.calibrate_sensor`). Either way the
        scene is validated before it is written, atomically: a failed calibration writes nothing."""
        from tactile_learn.thermal_recordings import read_recordings

        cfg = _config(scene)
        touches = [t for t in read_recordings(source, class_map=class_map) if t.material]
        if not touches:
            raise DataError(f"{source}: no labelled touches to calibrate from")
        names = {m.name for m in cfg.material_list}
        real = (
            channels is not None
            or class_map is not None
            or cfg.dynamic
            or any(t.passive_c is not None or t.force is not None for t in touches)
            or any(t.material not in names for t in touches)
        )
        if real:
            from synth.io import atomic_write_json
            from tactile_learn.calibration.thermal_scene import CHANNEL_CHOICES, calibrate_recordings, write_scene

            has_passive = all(t.passive_c is not None for t in touches)
            chosen = CHANNEL_CHOICES[channels or ("all" if has_passive else "heated")]
            calibrated_scene, report = calibrate_recordings(source, chosen, class_map, name=f"{scene.name}_calibrated")
            write_scene(calibrated_scene, out, report)
            report_path = Path(out).with_suffix(".json")
            atomic_write_json(report_path, report)
            return {
                "scene": str(out),
                "report": str(report_path),
                "touches": len(touches),
                "classes": list(calibrated_scene.sensor.class_names),
                "residual": report["residual"],
                "at_bound": report["at_bound"],
                "not_identified": report["not_identified"],
                "seconds": report["solver"]["seconds"],
            }
        from tactile_learn.calibration.thermal_seed import calibrate_sensor

        fitted, summary = calibrate_sensor(touches, cfg)
        calibrated = dataclasses.replace(
            scene,
            sensor=fitted,
            name=f"{scene.name}_calibrated",
            description=f"{scene.description} (sensor calibrated from {len(touches)} touches)".strip(),
        )
        text = dumps_toml(calibrated.to_dict())
        try:  # the scene must load back before it is written
            parse_scene(calibrated.to_dict(), str(out))
        except ConfigError as exc:
            raise DataError(
                f"{out}: the calibrated scene does not validate ({exc}); nothing written: calibrate with more, "
                "longer or cleaner touches, or give the onsets (touches.csv column onset_s)"
            ) from None
        header = "# Written by `tactile-learn calibrate --task thermal`: the sensor's own parameters.\n"
        atomic_write_text(out, header + text)
        return {"scene": str(out), "touches": len(touches), **summary}

    # ---- learning (torch inside) ---------------------------------------------------------------

    def fit_stats(self, arrays: dict[str, np.ndarray], scene: Scene) -> dict[str, Any]:
        cfg = _config(scene)
        touched = np.asarray(arrays["latent_material"][:2000]) >= 0
        scales = []
        for channel in cfg.channels:
            readings = np.asarray(arrays["readings" if channel == "heated" else channel][:2000], dtype=np.float64)
            # typical size of a contact's temperature change: the spread of record minus its start
            swing = np.abs(readings - readings[..., :1]).max(axis=-1)
            scales.append(max(float(np.median(swing[touched])) if touched.any() else 1.0, 0.1))
        return {
            "classes": list(class_names(scene)),
            "channels": list(cfg.channels),
            "window": cfg.window_samples,
            "sampling_hz": cfg.readout.sampling_hz,
            "scale_k": scales[0],
            "channel_scale_k": scales,
            "noise_k": cfg.readout.noise_k,
        }

    def training_batch(
        self, arrays: dict[str, np.ndarray], scene: Scene, rng: np.random.Generator
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Windows of 4 random pixels of every touch, each ending a random time after its onset
        (uniform from 0.1 s up to the contact's end, at most ``window_s - 0.2`` s), plus a random
        offset of the whole curve (absolute temperature carries no label; with several channels the
        same offset for all, so their difference is kept).

        Uniform, not log-uniform: a log-uniform half put most windows on the first few hundred
        milliseconds, where materials are least separable, and starved long contacts; on the
        seed's three materials that left the network behind the physics fit at 2 s (92 against
        56 errors in 9,714 contact pixels); trained on uniform durations it makes 6.

        A real-sensor scene's records start 0.3-3 s before their contact like a logger's that
        starts on a trigger: samples before that repeat the first one, as real windows are padded."""
        cfg = _config(scene)
        fs = cfg.readout.sampling_hz
        width = cfg.window_samples
        readings = np.asarray(arrays["readings"], dtype=np.float32)
        b, p, r = readings.shape
        # a few pixels of every touch (pixels on one object are alike: more touches per step)
        keep = min(p, _TRAIN_PIXELS)
        pick = np.argsort(rng.random((b, p)), axis=1)[:, :keep]
        rows = (np.arange(b)[:, None] * p + pick).ravel()
        onset = np.asarray(arrays["latent_onset_s"], dtype=np.float64).reshape(-1)[rows]
        release = np.asarray(arrays["latent_release_s"], dtype=np.float64).reshape(-1)[rows]
        material = np.asarray(arrays["latent_material"]).reshape(-1)[rows]
        labels = labels_from_materials(material, len(cfg.material_list), cfg)
        n = b * keep
        hi = np.maximum(np.minimum(release - onset, cfg.window_s - _TRAIN_BASE_S), _TRAIN_MIN_S + 1e-3)
        d = _TRAIN_MIN_S + rng.random(n) * (hi - _TRAIN_MIN_S)
        end = np.minimum(np.floor((onset + d) * fs).astype(np.int64) + 1, r)
        offset = rng.uniform(-3.0, 3.0, size=(n, 1)).astype(np.float32)
        first = None
        if cfg.dynamic:
            lead = rng.uniform(*_RECORD_LEAD_S, size=n)
            first = np.clip(np.floor((onset - lead) * fs).astype(np.int64), 0, r - 1)
        parts = []
        for channel in cfg.channels:
            source = readings if channel == "heated" else np.asarray(arrays[channel], dtype=np.float32)
            records = source.reshape(b * p, r)[rows]
            if first is not None:  # the record starts at `first`: earlier samples repeat it
                idx = np.maximum(np.arange(r)[None, :], first[:, None])
                records = np.take_along_axis(records, idx, axis=1)
            parts.append(windows(records, np.full(n, r), end, width) + offset)
        x = parts[0] if len(parts) == 1 else np.stack(parts, axis=1)
        return x, {"label": labels}

    def build_net(self, size: str, scene: Scene, stats: dict[str, Any]) -> torch.nn.Module:
        from tactile_learn.nets.thermal import build_thermal_net

        return build_thermal_net(size, scene, stats)

    def train_forward(self, net: torch.nn.Module, inputs: torch.Tensor) -> torch.Tensor:
        return net.logits(inputs)  # type: ignore[operator]

    def loss(self, output: torch.Tensor, targets: dict[str, torch.Tensor]) -> torch.Tensor:
        from tactile_learn.nets.thermal import thermal_loss

        return thermal_loss(output, targets["label"])


def oracle_accuracy_by_duration(data: EvalData, limit: int | None = None) -> dict[str, Any]:
    """``oracle_accuracy_by_duration`` (and the oracle's family accuracy) on ``data``: the physics
    fit given each pixel's true heat capacity, loss and heater (``latent_heat_capacity_j_m2k``,
    ``latent_loss_w_m2k``, ``latent_heater_w_m2``), the material and every nuisance unknown (their
    ranges known from the scene). ``limit``: first rows only."""
    from tactile_learn.estimators.classical.physics_fit import PhysicsFitEstimator

    for key in ("latent_heat_capacity_j_m2k", "latent_loss_w_m2k", "latent_heater_w_m2"):
        if key not in data.extra:
            raise DataError(f"{data.source}: the oracle needs {key} (generate with the 'latent' output)")
    if limit is not None:
        data = data.subset(slice(0, limit))
    out: dict[str, Any] = {"oracle_accuracy_by_duration": {}, "oracle_family_accuracy_by_duration": {}}
    materials = _config(data.scene).material_list
    for d in DURATIONS_S:
        x, valid = view(data, d)
        if not valid.any():
            continue
        oracle = PhysicsFitEstimator(
            data.scene,
            heat_capacity=data.extra["latent_heat_capacity_j_m2k"][valid],
            loss=data.extra["latent_loss_w_m2k"][valid],
            heater=data.extra["latent_heater_w_m2"][valid],
        ).prepare()
        m = thermal_metrics(oracle.predict_proba(x[valid]), data.truth["label"][valid], materials)
        out["oracle_accuracy_by_duration"][_key(d)] = m["accuracy"]
        out["oracle_family_accuracy_by_duration"][_key(d)] = m["family_accuracy"]
    return out
