"""The user recording format for the thermal fingertip, read and written.

A recording directory holds ``touches.csv`` and one CSV per touch::

    touches.csv     file,material[,onset_s][,...any other column, e.g. condition,session]
    touch-000.csv   time_s,temperature_c[,passive_c][,force]   (one row per sample, time increasing)

``file`` is the touch's CSV, relative to the directory; ``material`` the touch's label (empty or
``?`` for an unlabelled touch, which calibration and accuracy skip). A label is a library material
(``tactile-learn materials`` lists them), a material family (``metal``, ``wood``, ...: every library
material of that family) or one of the user's own classes (a ``[classes]`` TOML mapping names to
materials or families, see :func:`synth.materials.load_class_map`). ``onset_s`` (optional) is the
contact onset in the touch's own time base; when absent or empty it is found from the ``force``
column when there is one (:func:`press_onset`), else from the temperature curve. Extra columns are
kept as strings (``eval --group-by`` breaks results down by them).

Touch files: ``temperature_c`` (the heated thermistor, degC) is required; ``passive_c`` (an unheated
thermistor on the same fingertip, degC) and ``force`` (any unit: only its shape is used) are
optional. Records may differ in length and sampling rate (they are resampled to the scene's rate).

Every problem is a :class:`~synth.errors.DataError` naming the file (and row): a missing
``touches.csv`` or column, an unknown label (with the list of accepted ones), a missing, empty or
non-numeric touch file, NaN, and time that does not strictly increase.
"""

from __future__ import annotations

import csv
import io
import math
import shutil
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from synth.errors import ConfigError, DataError
from synth.io import atomic_write_text
from synth.materials import accepted_labels, resolve_label
from synth.sensors.thermal.physics import ABSOLUTE_ZERO_C
from tactile_learn.thermal_signal import FORCE_FILTER_S, press_onset, press_profile  # re-exported: old home

__all__ = [
    "FORCE_FILTER_S",
    "INDEX",
    "OPTIONAL_COLUMNS",
    "Touch",
    "copy_recordings",
    "press_onset",
    "press_profile",
    "read_csv_text",
    "read_recordings",
    "read_touch",
    "read_touch_columns",
    "resample",
    "resample_channel",
    "select_recordings",
    "write_recordings",
]

INDEX = "touches.csv"
UNLABELLED = ("", "?")
#: optional per-sample columns of a touch file, after time_s and temperature_c
OPTIONAL_COLUMNS = ("passive_c", "force")
#: most samples a record may have once resampled (a guard against time_s in the wrong unit)
MAX_SAMPLES = 10_000_000
#: DictReader key of the values in a row beyond its header's columns
_EXTRA = "\x00extra"


@dataclass
class Touch:
    """One recorded touch: its samples, label and optional onset (``passive_c``, ``force``: the
    optional channels, ``None`` when the file has none)."""

    file: str
    time_s: np.ndarray
    temperature_c: np.ndarray
    material: str | None = None
    onset_s: float | None = None
    info: dict[str, str] = field(default_factory=dict)
    passive_c: np.ndarray | None = None
    force: np.ndarray | None = None

    @property
    def sampling_hz(self) -> float:
        """Median sampling rate of the record."""
        return float(1.0 / np.median(np.diff(self.time_s)))  # time strictly increases: diff > 0

    def channel(self, name: str) -> np.ndarray:
        """The samples of ``temperature_c``, ``passive_c`` or ``force`` (a DataError if absent)."""
        values = getattr(self, name, None) if name in ("temperature_c", *OPTIONAL_COLUMNS) else None
        if values is None:
            raise DataError(f"{self.file}: no {name} column")
        return np.asarray(values)


def _float(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise DataError(f"{where}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise DataError(f"{where}: {text!r} is not a finite number")
    return value


def read_csv_text(path: Path) -> str:
    """A CSV's text (a spreadsheet's byte-order mark dropped); unreadable files are a DataError."""
    try:
        return path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"{path}: cannot be read ({exc})") from None


def read_touch_columns(path: str | Path) -> dict[str, np.ndarray]:
    """``time_s``, ``temperature_c`` and whichever of :data:`OPTIONAL_COLUMNS` the touch CSV has
    (float64), validated."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: touch file not found")
    text = read_csv_text(path)
    rows = [r for r in csv.reader(io.StringIO(text)) if r and any(c.strip() for c in r)]
    if not rows:
        raise DataError(f"{path}: empty file (expected a header time_s,temperature_c and samples)")
    header = [c.strip().lower() for c in rows[0]]
    missing = [c for c in ("time_s", "temperature_c") if c not in header]
    if missing:
        raise DataError(f"{path}: missing column(s) {', '.join(missing)} (header: {','.join(rows[0])})")
    names = ["time_s", "temperature_c", *(c for c in OPTIONAL_COLUMNS if c in header)]
    cols = [header.index(c) for c in names]
    if len(rows) < 3:
        raise DataError(f"{path}: needs at least 2 samples, has {len(rows) - 1}")
    values = np.empty((len(names), len(rows) - 1))
    for n, row in enumerate(rows[1:]):
        where = f"{path}: row {n + 2}"
        if len(row) <= max(cols):
            raise DataError(f"{where}: expected {len(header)} columns, got {len(row)}")
        for j, c in enumerate(cols):
            values[j, n] = _float(row[c].strip(), where)
    for name, column in zip(names, values, strict=True):
        if name.endswith("_c") and (column <= ABSOLUTE_ZERO_C).any():
            bad = int(np.argmax(column <= ABSOLUTE_ZERO_C)) + 2  # row number (header is row 1)
            raise DataError(f"{path}: row {bad}: {name} {column[bad - 2]:g} degC is at or below absolute zero")
    time = values[0]
    with np.errstate(over="ignore"):  # a span beyond float64 is +-inf: still ordered right
        step = np.diff(time)
    if (step <= 0).any():
        bad = int(np.argmax(step <= 0)) + 3  # row number of the offending sample (header is row 1)
        raise DataError(f"{path}: row {bad}: time_s does not increase ({time[bad - 3]} then {time[bad - 2]})")
    return dict(zip(names, values, strict=True))


def read_touch(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """``time_s`` and ``temperature_c`` of one touch CSV (float64), validated."""
    columns = read_touch_columns(path)
    return columns["time_s"], columns["temperature_c"]


def _label(
    label: str,
    where: str,
    materials: Sequence[str] | None,
    classes: dict[str, tuple[str, ...]] | None,
    class_map: dict[str, tuple[str, ...]] | None,
) -> str:
    """The label as the caller's scene names it (see :func:`read_recordings`)."""
    if classes is not None:
        if label in classes:
            return label
        try:
            mats = {m.name for m in resolve_label(label, class_map)}
        except ConfigError:
            mats = set()
        owners = [name for name, members in classes.items() if mats and mats <= set(members)]
        if len(owners) == 1:
            return owners[0]
        raise DataError(f"{where}: label {label!r} is not one of the classes {', '.join(classes)}")
    try:
        resolved = resolve_label(label, class_map)
    except ConfigError:
        kind = "material" if materials is not None else "label"
        raise DataError(f"{where}: unknown {kind} {label!r} (accepted: {accepted_labels(class_map)})") from None
    if materials is None:
        return label.strip() if len(resolved) > 1 or (class_map and label.strip() in class_map) else resolved[0].name
    if len(resolved) != 1:
        raise DataError(
            f"{where}: {label!r} names {len(resolved)} materials; this scene classifies single materials "
            f"({', '.join(materials)}): evaluate with a scene that has classes (--scene CALIBRATED.toml, "
            "from calibrate or adapt), or label touches by material"
        )
    allowed = set(materials)
    if resolved[0].name not in allowed:
        raise DataError(
            f"{where}: material {resolved[0].name!r} is not in the scene's list ({', '.join(sorted(allowed))})"
        )
    return resolved[0].name


def read_recordings(
    path: str | Path,
    materials: Sequence[str] | None = None,
    *,
    classes: dict[str, tuple[str, ...]] | None = None,
    class_map: dict[str, tuple[str, ...]] | None = None,
) -> list[Touch]:
    """Every touch listed in ``path/touches.csv``.

    Labels: with ``classes`` (a scene's classes: name -> library materials), a label must be a class
    name or a material (or family) inside exactly one class, and reads back as the class name; with
    ``materials`` (a scene's material list), a label must be one of those materials; with neither,
    any label :func:`synth.materials.resolve_label` accepts (``class_map``: the user's classes) is
    kept (a single material by its library name, a family or class by its own name).
    """
    folder = Path(path)
    index = folder / INDEX
    if not folder.is_dir():
        raise DataError(f"{folder}: no such recording directory")
    if not index.is_file():
        raise DataError(f"{folder}: no {INDEX} (a recording directory lists its touches there: file,material)")
    text = read_csv_text(index)
    reader = csv.DictReader(io.StringIO(text), restkey=_EXTRA)
    if not reader.fieldnames:
        raise DataError(f"{index}: empty file (expected a header file,material and one row per touch)")
    fields = [f.strip().lower() for f in (reader.fieldnames or [])]
    missing = [c for c in ("file", "material") if c not in fields]
    if missing:
        raise DataError(
            f"{index}: missing column(s) {', '.join(missing)} (header: {','.join(reader.fieldnames or [])})"
        )
    touches: list[Touch] = []
    for n, raw in enumerate(reader):
        row = {(k or "").strip().lower(): (v or "").strip() for k, v in raw.items() if k != _EXTRA}
        where = f"{index}: row {n + 2}"
        if _EXTRA in raw:
            raise DataError(f"{where}: {len(fields) + len(raw[_EXTRA])} fields, the header has {len(fields)}")
        if not row.get("file"):
            raise DataError(f"{where}: empty file name")
        label = row.get("material", "")
        material = None if label in UNLABELLED else _label(label, where, materials, classes, class_map)
        onset = _float(row["onset_s"], f"{where}: onset_s") if row.get("onset_s") else None
        columns = read_touch_columns(folder / row["file"])
        info = {k: v for k, v in row.items() if k not in ("file", "material", "onset_s")}
        touches.append(
            Touch(
                row["file"],
                columns["time_s"],
                columns["temperature_c"],
                material,
                onset,
                info,
                passive_c=columns.get("passive_c"),
                force=columns.get("force"),
            )
        )
    if not touches:
        raise DataError(f"{index}: lists no touches")
    return touches


def write_recordings(path: str | Path, touches: Iterable[Touch]) -> Path:
    """Write ``touches`` as a recording directory (atomic per file); returns the index path."""
    folder = Path(path)
    folder.mkdir(parents=True, exist_ok=True)
    touches = list(touches)
    extra = sorted({k for t in touches for k in t.info})
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    has_onset = any(t.onset_s is not None for t in touches)
    writer.writerow(["file", "material", *(["onset_s"] if has_onset else []), *extra])
    for t in touches:
        optional = [(c, getattr(t, c)) for c in OPTIONAL_COLUMNS if getattr(t, c) is not None]
        body = io.StringIO()
        body.write(",".join(["time_s", "temperature_c", *(c for c, _ in optional)]) + "\n")
        for i, (a, b) in enumerate(zip(t.time_s, t.temperature_c, strict=True)):
            more = "".join(f",{float(v[i]):.5f}" for _, v in optional)
            body.write(f"{float(a)!r},{b:.5f}{more}\n")  # time to the float: any rate reads back
        atomic_write_text(folder / t.file, body.getvalue())
        onset = [] if not has_onset else ["" if t.onset_s is None else f"{t.onset_s:.6f}"]
        writer.writerow([t.file, t.material or "", *onset, *(t.info.get(k, "") for k in extra)])
    atomic_write_text(folder / INDEX, out.getvalue())
    return folder / INDEX


def _read_index(folder: Path, column: str) -> tuple[Path, list[str], list[dict[str, str]]]:
    """The recording folder's index (touches.csv): its path, columns and rows; ``column`` must be one."""
    index = folder / INDEX
    if not index.is_file():
        raise DataError(f"{folder}: no {INDEX}")
    reader = csv.DictReader(io.StringIO(read_csv_text(index)))
    fields = list(reader.fieldnames or [])
    if column not in fields:
        raise DataError(f"{index}: no column {column!r} (columns: {', '.join(fields)})")
    return index, fields, list(reader)


def _write_index(target: Path, fields: list[str], rows: list[dict[str, str]]) -> None:
    """``target``/touches.csv holding ``rows``, written atomically and last (a folder without it is no
    recording set)."""
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    target.mkdir(parents=True, exist_ok=True)
    atomic_write_text(target / INDEX, text.getvalue())


def select_recordings(
    source: str | Path, out: str | Path, column: str, values: Sequence[str], keep: bool = True
) -> Path:
    """A recording folder ``out`` whose touches.csv lists the touches of ``source`` whose ``column``
    is (``keep``) or is not (not ``keep``) one of ``values`` (e.g. one session as the labelled set,
    the rest as the test set). The touch files stay where they are: the new index names them by
    their absolute path (``out`` is a working folder, never a project file)."""
    folder, target = Path(source), Path(out)
    index, fields, rows = _read_index(folder, column)
    rows = [r for r in rows if (r[column] in values) == keep]
    if not rows:
        raise DataError(f"{index}: no touch with {column} {'in' if keep else 'outside'} {', '.join(values)}")
    _write_index(target, fields, [{**r, "file": str((folder / r["file"]).resolve())} for r in rows])
    return target


def copy_recordings(source: str | Path, target: str | Path) -> Path:
    """A self-contained copy of the recording folder ``source`` (its touches.csv and every touch
    file it names, flat under ``target``), so an adapt folder keeps the touches it learnt from."""
    folder, out = Path(source), Path(target)
    index, fields, rows = _read_index(folder, "file")
    names = [Path(r["file"]).name for r in rows]
    if len(set(names)) != len(names):
        raise DataError(f"{index}: two touch files share a name; give each touch its own file name")
    out.mkdir(parents=True, exist_ok=True)
    for row, name in zip(rows, names, strict=True):
        if not (folder / row["file"]).is_file():
            raise DataError(f"{index}: touch file {row['file']!r} does not exist")
        shutil.copyfile(folder / row["file"], out / name)  # an absolute name (a selection's index) stays absolute
    _write_index(out, fields, [{**row, "file": name} for row, name in zip(rows, names, strict=True)])
    return out


def _grid(touch: Touch, fs: float) -> np.ndarray:
    t0, t1 = float(touch.time_s[0]), float(touch.time_s[-1])
    span = (t1 - t0) * fs
    if not span < MAX_SAMPLES:  # also catches an infinite span
        raise DataError(
            f"{touch.file}: time_s spans {t1 - t0:g} s, over {MAX_SAMPLES} samples at {fs:g} Hz (is time_s in seconds?)"
        )
    n = math.floor(span + 1e-9) + 1
    return t0 + np.arange(n) / fs


def resample_channel(touch: Touch, name: str, fs: float) -> np.ndarray:
    """Channel ``name`` of the touch on a uniform grid at ``fs`` Hz from its first sample."""
    return np.interp(_grid(touch, fs), touch.time_s, touch.channel(name))


def resample(touch: Touch, fs: float) -> tuple[np.ndarray, float | None]:
    """The heated channel on a uniform grid at ``fs`` Hz from its first sample (linear
    interpolation), and its onset in samples of that grid (``None`` when unknown)."""
    values = resample_channel(touch, "temperature_c", fs)
    onset = None if touch.onset_s is None else (touch.onset_s - float(touch.time_s[0])) * fs
    return values, onset
