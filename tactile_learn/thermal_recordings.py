"""The user recording format for the thermal fingertip, read and written.

A recording directory holds ``touches.csv`` and one CSV per touch::

    touches.csv                     file,material[,onset_s][,object_c][,...any other column]
    touch-000.csv                   time_s,temperature_c   (one row per sample, time increasing)

``file`` is the touch's CSV, relative to the directory; ``material`` a name from the material
library (``synth.materials``; empty or ``?`` for an unlabelled touch, which calibration and
accuracy skip); ``onset_s`` (optional) the contact onset in the touch's own time base (when absent,
or empty, it is detected). Extra columns are kept as strings. The onset may be anywhere in the
record; records may differ in length and sampling rate (they are resampled to the scene's rate).

Every problem is a :class:`~synth.errors.DataError` naming the file (and row): a missing
``touches.csv`` or column, an unknown material, a missing, empty or non-numeric touch file, NaN,
and time that does not strictly increase.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from synth.errors import ConfigError, DataError
from synth.io import atomic_write_text
from synth.materials import get_material

__all__ = ["INDEX", "Touch", "read_recordings", "read_touch", "resample", "write_recordings"]

INDEX = "touches.csv"
UNLABELLED = ("", "?")
#: most samples a record may have once resampled (a guard against time_s in the wrong unit)
MAX_SAMPLES = 10_000_000
#: DictReader key of the values in a row beyond its header's columns
_EXTRA = "\x00extra"


@dataclass
class Touch:
    """One recorded touch: its samples, label and optional onset."""

    file: str
    time_s: np.ndarray
    temperature_c: np.ndarray
    material: str | None = None
    onset_s: float | None = None
    info: dict[str, str] = field(default_factory=dict)

    @property
    def sampling_hz(self) -> float:
        """Median sampling rate of the record."""
        return float(1.0 / np.median(np.diff(self.time_s)))  # time strictly increases: diff > 0


def _float(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise DataError(f"{where}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise DataError(f"{where}: {text!r} is not a finite number")
    return value


def _read_text(path: Path) -> str:
    """A CSV's text (a spreadsheet's byte-order mark dropped); unreadable files are a DataError."""
    try:
        return path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"{path}: cannot be read ({exc})") from None


def read_touch(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """``time_s`` and ``temperature_c`` of one touch CSV (float64), validated."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: touch file not found")
    text = _read_text(path)
    rows = [r for r in csv.reader(io.StringIO(text)) if r and any(c.strip() for c in r)]
    if not rows:
        raise DataError(f"{path}: empty file (expected a header time_s,temperature_c and samples)")
    header = [c.strip().lower() for c in rows[0]]
    missing = [c for c in ("time_s", "temperature_c") if c not in header]
    if missing:
        raise DataError(f"{path}: missing column(s) {', '.join(missing)} (header: {','.join(rows[0])})")
    it, ix = header.index("time_s"), header.index("temperature_c")
    if len(rows) < 3:
        raise DataError(f"{path}: needs at least 2 samples, has {len(rows) - 1}")
    time = np.empty(len(rows) - 1)
    temp = np.empty(len(rows) - 1)
    for n, row in enumerate(rows[1:]):
        where = f"{path}: row {n + 2}"
        if len(row) <= max(it, ix):
            raise DataError(f"{where}: expected {len(header)} columns, got {len(row)}")
        time[n] = _float(row[it].strip(), where)
        temp[n] = _float(row[ix].strip(), where)
    with np.errstate(over="ignore"):  # a span beyond float64 is +-inf: still ordered right
        step = np.diff(time)
    if (step <= 0).any():
        bad = int(np.argmax(step <= 0)) + 3  # row number of the offending sample (header is row 1)
        raise DataError(f"{path}: row {bad}: time_s does not increase ({time[bad - 3]} then {time[bad - 2]})")
    return time, temp


def read_recordings(path: str | Path, materials: Sequence[str] | None = None) -> list[Touch]:
    """Every touch listed in ``path/touches.csv``. ``materials`` (names) restricts the labels
    allowed (e.g. a scene's material list); library names are always checked."""
    folder = Path(path)
    index = folder / INDEX
    if not folder.is_dir():
        raise DataError(f"{folder}: no such recording directory")
    if not index.is_file():
        raise DataError(f"{folder}: no {INDEX} (a recording directory lists its touches there: file,material)")
    text = _read_text(index)
    reader = csv.DictReader(io.StringIO(text), restkey=_EXTRA)
    if not reader.fieldnames:
        raise DataError(f"{index}: empty file (expected a header file,material and one row per touch)")
    fields = [f.strip().lower() for f in (reader.fieldnames or [])]
    missing = [c for c in ("file", "material") if c not in fields]
    if missing:
        raise DataError(
            f"{index}: missing column(s) {', '.join(missing)} (header: {','.join(reader.fieldnames or [])})"
        )
    allowed = None if materials is None else {get_material(m).name for m in materials}
    touches: list[Touch] = []
    for n, raw in enumerate(reader):
        row = {(k or "").strip().lower(): (v or "").strip() for k, v in raw.items() if k != _EXTRA}
        where = f"{index}: row {n + 2}"
        if _EXTRA in raw:
            raise DataError(f"{where}: {len(fields) + len(raw[_EXTRA])} fields, the header has {len(fields)}")
        if not row.get("file"):
            raise DataError(f"{where}: empty file name")
        label = row.get("material", "")
        material = None
        if label not in UNLABELLED:
            try:
                material = get_material(label).name
            except ConfigError:
                raise DataError(f"{where}: unknown material {label!r}") from None
            if allowed is not None and material not in allowed:
                raise DataError(
                    f"{where}: material {material!r} is not in the scene's list ({', '.join(sorted(allowed))})"
                )
        onset = _float(row["onset_s"], f"{where}: onset_s") if row.get("onset_s") else None
        time, temp = read_touch(folder / row["file"])
        info = {k: v for k, v in row.items() if k not in ("file", "material", "onset_s")}
        touches.append(Touch(row["file"], time, temp, material, onset, info))
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
        body = io.StringIO()
        body.write("time_s,temperature_c\n")
        for a, b in zip(t.time_s, t.temperature_c, strict=True):
            body.write(f"{float(a)!r},{b:.5f}\n")  # time to the float: any rate reads back
        atomic_write_text(folder / t.file, body.getvalue())
        onset = [] if not has_onset else ["" if t.onset_s is None else f"{t.onset_s:.6f}"]
        writer.writerow([t.file, t.material or "", *onset, *(t.info.get(k, "") for k in extra)])
    atomic_write_text(folder / INDEX, out.getvalue())
    return folder / INDEX


def resample(touch: Touch, fs: float) -> tuple[np.ndarray, float | None]:
    """The touch on a uniform grid at ``fs`` Hz from its first sample (linear interpolation), and
    its onset in samples of that grid (``None`` when unknown)."""
    t0, t1 = float(touch.time_s[0]), float(touch.time_s[-1])
    span = (t1 - t0) * fs
    if not span < MAX_SAMPLES:  # also catches an infinite span
        raise DataError(
            f"{touch.file}: time_s spans {t1 - t0:g} s, over {MAX_SAMPLES} samples at {fs:g} Hz (is time_s in seconds?)"
        )
    n = math.floor(span + 1e-9) + 1
    grid = t0 + np.arange(n) / fs
    values = np.interp(grid, touch.time_s, touch.temperature_c)
    onset = None if touch.onset_s is None else (touch.onset_s - t0) * fs
    return values, onset
