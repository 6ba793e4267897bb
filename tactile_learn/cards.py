"""Model cards re-verified: every held-out metric a card records, measured again.

A card's ``metrics`` hold, besides the training run's ``validation``, one entry per held-out set:

- a dataset (``{"data": {"path", "scene", "seed", "n", "shard_size", "n_frames"}, "values": {...}}``): by
  ``tactile-learn export --test`` and ``tactile-learn cards add --data``;
- a suite (``{"suite", "seed", "n_frames_per_family", "families", "mean_over_families"}``): by
  ``tactile-learn cards add --suite``.

:func:`verify_card` regenerates each set from what the card names (scene, seed and size; datasets are
generated, never shipped), evaluates the model on it with the runtime, and compares every recorded
number with the one measured now. Generation is bit-for-bit deterministic for a seed and the model
is the same file (its SHA-256 is checked), so on an unchanged simulator the figures agree exactly;
the default tolerance (:data:`RTOL`) only absorbs float32 rounding of a figure summed in another
order, and the report counts exact and merely close figures apart. A difference beyond it means the
simulator, a metric or the model changed since the card was written; the report names each figure.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from synth.dataset import generate
from synth.errors import ConfigError, ModelError, TactileError
from synth.io import atomic_write_json, json_ready
from synth.scene import load_scene
from tactile_learn.methods import resolve_method
from tactile_learn.provenance import command_line, dataset_record, portable_path
from tactile_learn.runtime import OnnxEstimator, card_path, read_card
from tactile_learn.tasks import get_task

__all__ = ["RTOL", "add_metrics", "compare_values", "dataset_entry", "heldout_sets", "suite_entry", "verify_card"]

#: relative tolerance of a re-measured figure (plus ``ATOL`` absolute, for figures that are zero):
#: figures computed in float32 (e.g. the strips readings residual) move in their 7th digit when an
#: operator sums in another order; anything larger is a real change. ``rtol=0`` asks for bit equality.
RTOL = 1e-6
ATOL = 1e-12
#: ``synth.dataset.generate``'s default shard size: what a card that does not record one was made with
DEFAULT_SHARD_SIZE = 8192


def heldout_sets(card: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """The card's held-out entries by name (every metrics entry but the run's ``validation``)."""
    return {name: entry for name, entry in card.get("metrics", {}).items() if name != "validation"}


def _leaves(value: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(dotted key, leaf) of a nested record; list items are keyed by their index."""
    if isinstance(value, dict):
        for key, item in value.items():
            yield from _leaves(item, f"{prefix}.{key}" if prefix else str(key))
    elif isinstance(value, list):
        for i, item in enumerate(value):
            yield from _leaves(item, f"{prefix}[{i}]")
    else:
        yield prefix, value


def _match(recorded: Any, now: Any, rtol: float) -> str:
    """``"exact"``, ``"close"`` (within ``rtol`` relative) or ``"differs"`` (both sides JSON data)."""
    if recorded == now:
        return "exact"
    numbers = (int, float)
    both_numbers = all(isinstance(v, numbers) and not isinstance(v, bool) for v in (recorded, now))
    if both_numbers and abs(now - recorded) <= ATOL + rtol * abs(recorded):
        return "close"
    return "differs"


def compare_values(recorded: Any, now: Any, rtol: float = RTOL) -> list[dict[str, Any]]:
    """One row per recorded figure: ``{"key", "recorded", "now", "match", "ok"}``; ``match`` is
    ``exact``, ``close`` (within ``rtol``), ``differs`` or ``missing`` (no longer reported). ``now``
    is compared as a card records it (:func:`~synth.io.json_ready`: NaN is recorded as null).
    Figures reported now but never recorded are not rows."""
    measured = dict(_leaves(json_ready(now)))
    rows = []
    for key, value in _leaves(recorded):
        match = _match(value, measured[key], rtol) if key in measured else "missing"
        rows.append(
            {"key": key, "recorded": value, "now": measured.get(key), "match": match, "ok": match in ("exact", "close")}
        )
    return rows


def dataset_entry(task_name: str, model: str | Path, data: str | Path) -> dict[str, Any]:
    """A card's metrics entry for ``model`` on the dataset folder ``data``: what regenerates the data
    (:func:`~tactile_learn.provenance.dataset_record`) and the task's metrics on it."""
    task = get_task(task_name)
    frames = task.load_eval_data(data)
    values: dict[str, Any] = task.evaluate(resolve_method(task_name, str(model), frames.scene), frames)
    return {"data": dataset_record(data, len(frames)), "values": values}


def suite_entry(task_name: str, model: str | Path, suite_name: str, n: int | None, seed: int) -> dict[str, Any]:
    """A card's metrics entry for ``model`` on a suite: per family (``n`` frames each, default the
    suite's) and their mean."""
    from synth.suite import load_suite
    from tactile_learn.suites import evaluate_suite, suite_eval_data

    suite = load_suite(suite_name)
    frames = suite_eval_data(suite, n, seed)
    report = evaluate_suite(resolve_method(task_name, str(model), suite.base), frames, task_name)
    return {
        "suite": suite.name,
        "seed": seed,
        "n_frames_per_family": {k: len(v) for k, v in frames.items()},
        "families": report["families"],
        "mean_over_families": report["mean_over_families"],
    }


def add_metrics(
    model: str | Path,
    name: str,
    *,
    data: str | Path | None = None,
    suite: str | None = None,
    n: int | None = None,
    command: str | None = None,
) -> dict[str, Any]:
    """Measure ``model`` on a dataset folder or a suite and record it in its card under
    ``metrics.<name>`` with ``command`` (default: this process's command line); returns the entry."""
    if (data is None) == (suite is None):
        raise ConfigError("cards add: give either a dataset folder (--data) or a suite (--suite)")
    if name == "validation":
        raise ConfigError("cards add: 'validation' is the training run's own entry; choose another --name")
    card = read_card(model)
    if data is not None:
        entry = dataset_entry(card["task"], model, data)
    else:
        from tactile_learn.suites import SUITE_SEED

        entry = suite_entry(card["task"], model, str(suite), n, SUITE_SEED)
    card.setdefault("metrics", {})[name] = {**entry, "command": command or command_line()}
    atomic_write_json(card_path(model), card)
    return entry


def _regenerated(model: Path, data_entry: dict[str, Any], workdir: Path) -> Path:
    """The held-out dataset a card entry names, generated again in ``workdir`` (once per set)."""
    for field in ("scene", "seed", "n"):
        if data_entry.get(field) is None:
            raise ModelError(
                f"{model}: the card's held-out data {data_entry.get('path')!r} does not record its {field} "
                "(export --test and cards add record scene, seed and n)"
            )
    scene = load_scene(str(data_entry["scene"]))
    recorded_digest = data_entry.get("scene_digest")
    if recorded_digest and recorded_digest != scene.digest:  # the shipped scene was edited since
        raise ModelError(
            f"{model}: scene {scene.name!r} is not the one the card's held-out data was generated with "
            f"(digest {scene.digest[:12]} now, {str(recorded_digest)[:12]} recorded)"
        )
    folder = workdir / f"{scene.name}-{data_entry['seed']}-{data_entry['n']}-{data_entry.get('shard_size')}"
    if not (folder / "manifest.json").is_file():  # two entries on the same set share one generation
        shard_size = int(data_entry.get("shard_size") or DEFAULT_SHARD_SIZE)  # cards before it was recorded
        generate(scene, int(data_entry["n"]), int(data_entry["seed"]), folder, shard_size=shard_size)
    return folder


def _verify_set(task_name: str, path: Path, entry: dict[str, Any], folder: Path, rtol: float) -> dict[str, Any]:
    recorded: dict[str, Any]
    if "suite" in entry:
        per_family = set(entry.get("n_frames_per_family", {}).values())
        n = per_family.pop() if len(per_family) == 1 else None
        measured = suite_entry(task_name, path, str(entry["suite"]), n, int(entry["seed"]))
        keys = ("n_frames_per_family", "families", "mean_over_families")
        recorded = {k: entry[k] for k in keys if k in entry}
        now = {k: measured[k] for k in keys}
    else:
        measured = dataset_entry(task_name, path, _regenerated(path, entry["data"], folder))
        recorded = {"n_frames": entry["data"].get("n_frames"), "values": entry["values"]}
        now = {"n_frames": measured["data"]["n_frames"], "values": measured["values"]}
    rows = compare_values(recorded, now, rtol)
    differ = [r for r in rows if not r["ok"]]
    return {
        "ok": not differ,
        "n_checked": len(rows),
        "n_exact": sum(r["match"] == "exact" for r in rows),
        "n_close": sum(r["match"] == "close" for r in rows),
        "n_differ": len(differ),
        "differ": differ,
        "close": [r for r in rows if r["match"] == "close"],
        "rows": rows,
    }


def verify_card(
    model: str | Path,
    *,
    names: list[str] | None = None,
    rtol: float = RTOL,
    workdir: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Re-measure the held-out metrics of ``model``'s card (all entries, or those in ``names``).

    Returns ``{"model", "task", "rtol", "ok", "sets": {name: {"ok", "n_checked", "n_differ",
    "differ": [rows that moved], "rows": [every row]}}}``; datasets are generated in ``workdir``
    (default: a temporary folder, removed afterwards)."""
    path = Path(model)
    card = read_card(path)
    entries = heldout_sets(card)
    unknown = sorted(set(names or ()) - set(entries))
    if unknown:
        raise ModelError(f"{path}: the card has no held-out metrics {', '.join(unknown)} (it has {', '.join(entries)})")
    try:  # a corrupt or mismatched model fails every set: found once, before any set is generated
        OnnxEstimator(path, card=card).prepare()
        model_error = None
    except TactileError as exc:
        model_error = str(exc)
    with tempfile.TemporaryDirectory(prefix="tl-cards-") as tmp:
        folder = Path(workdir) if workdir is not None else Path(tmp)
        sets: dict[str, Any] = {}
        for name, entry in entries.items():
            if names and name not in names:
                continue
            if progress:
                progress(f"{path.name}: {name}")
            try:
                if model_error is not None:
                    raise ModelError(model_error)
                sets[name] = _verify_set(card["task"], path, entry, folder, rtol)
            except TactileError as exc:  # this set cannot be re-measured: say why, go on with the others
                sets[name] = {"ok": False, "error": str(exc), "n_checked": 0, "n_differ": 0, "differ": []}
    return {
        "model": portable_path(path),
        "task": card["task"],
        "rtol": rtol,
        "ok": all(s["ok"] for s in sets.values()),
        "sets": sets,
    }
