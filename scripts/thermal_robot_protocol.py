"""Issue 11's protocol on the real robot recordings: label one session, classify every other touch.

    python scripts/thermal_robot_protocol.py --label R_1 --json results/thermal_robot.json
    python scripts/thermal_robot_protocol.py --label R_1,R_4,R_7 --json results/thermal_robot_sessions.json

For every labelled session: ``adapt`` (calibrate on its 9 touches, simulate, train, validate on the
labelled touches, export) once per channel set (heated only; heated + passive), then every method
on every other touch of the folder: the learned model, the classical methods on the calibrated
scene (curve_match and physics_fit: the seed's, heated only; calibrated: the fitted sensor model,
every channel of the classifier), and two classifiers trained on the same labelled touches alone
(``tactile_learn.few_shot``): the onset-aligned PCA baseline and the press-aligned nearest touch
(curves read against press time, the force's running integral). Accuracy at 0.5 / 1 / 2 / 4 s of
contact (the onset: the force's half-plateau crossing), overall and per condition (M metal, W wood,
CW cooled wood). Beside them ``adapt_choice``: what ``adapt`` hands the user (its card's classifier
choice, :mod:`tactile_learn.thermal_choice`; ``tactile-learn eval --method ADAPT_FOLDER/``). With
several labelled sessions the JSON ends with ``summary``: per method the min and median over them
and for how many issue 11's floors hold. The data: ``--data``, else ``$TACTILE_THERMAL_ROBOT``, else
``../shared/data/thermal-robot`` beside the repository.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from synth.io import atomic_write_json
from tactile_learn.few_shot import FEW_SHOT_METHODS, few_shot_evaluate
from tactile_learn.methods import resolve_method
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.tasks.thermal import ThermalTask
from tactile_learn.thermal_adapt import CHANNEL_CHOICES, adapt_scene, calibrate_recordings, write_scene
from tactile_learn.thermal_choice import choice_evaluate, load_adapted, write_choice
from tactile_learn.thermal_recordings import select_recordings

DURATIONS = (0.5, 1.0, 2.0, 4.0)
ROOT = Path(__file__).resolve().parent.parent


def robot_data(path: str | None = None) -> Path:
    """The recordings folder: ``path``, ``$TACTILE_THERMAL_ROBOT`` or ``../shared/data/thermal-robot``."""
    return Path(path or os.environ.get("TACTILE_THERMAL_ROBOT") or ROOT.parent / "shared" / "data" / "thermal-robot")


def split(data: Path, labelled: str, out: Path) -> tuple[Path, Path]:
    """Two recording folders under ``out``: the labelled session's touches and every other one."""
    return (
        select_recordings(data, out / "labelled", "session", [labelled]),
        select_recordings(data, out / "test", "session", [labelled], keep=False),
    )


def _table(metrics: dict[str, Any]) -> dict[str, Any]:
    out = {"all": {k: metrics["accuracy_by_duration"].get(k) for k in map(_key, DURATIONS)}}
    for group, m in metrics.get("by_group", {}).items():
        out[group] = {k: m["accuracy_by_duration"].get(k) for k in map(_key, DURATIONS)}
    return out


def _key(d: float) -> str:
    return f"{d:g}" if d != int(d) else f"{d:.1f}"


def few_shot(labelled: Path, test: Path, scene: Any, method: str) -> dict[str, Any]:
    """A classifier trained on the labelled touches alone (:mod:`tactile_learn.few_shot`), one
    model per duration, on every channel of ``scene``; with its leave-one-out accuracy on the
    labelled touches (what a user can check without the other sessions)."""
    task = ThermalTask()
    train, data = task.load_eval_data(labelled, scene), task.load_eval_data(test, scene)
    metrics = few_shot_evaluate(method, train, data, DURATIONS, "condition")
    return {**_table(metrics), "leave_one_out": metrics["leave_one_out_by_duration"]}


def reuse_adapt(folder: Path, labelled: Path) -> dict[str, Any]:
    """The card of an adapt run already in ``folder``, its classifier choice made again from the
    labelled touches (the network is unchanged: what adapt does after training is cheap)."""
    from synth.io import atomic_write_json as write_json
    from tactile_learn.runtime import card_path, read_card

    model = folder / "model.onnx"
    network = OnnxEstimator(model).prepare()
    card = read_card(model)
    mark = time.perf_counter()
    card["classifier"] = write_choice(network, labelled, folder, network.card_scene_)
    timings = card["adapt"]["timings_s"]
    timings["choose_s"] = time.perf_counter() - mark
    timings["total_s"] = timings.get("total_s", 0.0) + timings["choose_s"]  # the earlier run's, plus the choice
    write_json(card_path(model), card)
    return card


def run_session(data: Path, labelled_session: str, work: Path, args: argparse.Namespace) -> dict[str, Any]:
    labelled, test = split(data, labelled_session, work / labelled_session)
    task = ThermalTask()
    out: dict[str, Any] = {"labelled": labelled_session}
    started = time.perf_counter()
    reuse = args.reuse and all((work / labelled_session / c / "model.json").is_file() for c in ("heated", "all"))
    if reuse:  # the calibration adapt wrote beside the networks it trained
        report = json.loads((work / labelled_session / "all" / "calibration.json").read_text())
        scene_all = None
        out["calibration_s"] = float(report["solver"]["seconds"])
    else:
        scene_all, report = calibrate_recordings(labelled, CHANNEL_CHOICES["all"], seed=args.seed)
        out["calibration_s"] = time.perf_counter() - started
    out["calibration"] = {
        "residual": report["residual"],
        "at_bound": report["at_bound"],
        "not_identified": report["not_identified"],
        "parameters": {k: v["value"] for k, v in report["parameters"].items()},
    }
    if scene_all is not None:
        write_scene(scene_all, work / labelled_session / "sensor.toml", report)
    for channels in ("heated", "all"):
        folder = work / labelled_session / channels
        mark = time.perf_counter()
        if reuse:
            # a network this command trained before (same settings): only the steps after it run again
            card = reuse_adapt(folder, labelled)
            seconds = float(card["adapt"]["timings_s"]["total_s"])
        else:
            assert scene_all is not None
            card = adapt_scene(
                scene_all,
                report,
                labelled,
                folder,
                channels=channels,
                n_train=args.n_train,
                epochs=args.epochs,
                seed=args.seed,
                threads=args.threads,
            )
            seconds = time.perf_counter() - mark + out["calibration_s"]
        model = OnnxEstimator(folder / "model.onnx").prepare()
        scene = model.card_scene_
        data_test = task.load_eval_data(test, scene)
        methods: dict[str, Any] = {}
        # what a user gets from adapt: the choice in its card (tactile-learn eval --method FOLDER/)
        network, kept = load_adapted(folder)  # type: ignore[misc]  # adapt always writes a choice
        chosen = choice_evaluate(task.load_eval_data(kept, scene), data_test, network, DURATIONS, "condition")
        methods["adapt_choice"] = {**_table(chosen), "choice": chosen["choice_by_duration"]}
        learned = task.evaluate(model, data_test, durations=DURATIONS, group_by="condition")
        methods["learned"] = _table(learned)
        for name in ("curve_match", "physics_fit", "calibrated"):
            estimator = resolve_method("thermal", name, scene)
            methods[name] = _table(task.evaluate(estimator, data_test, durations=DURATIONS, group_by="condition"))
        for name in FEW_SHOT_METHODS:
            methods[name] = few_shot(labelled, test, scene, name)
        out[channels] = {
            "methods": methods,
            "adapt_seconds": seconds,
            "labelled_accuracy": card["metrics"]["labelled_touches"]["values"]["accuracy_by_duration"],
            # the temporary work folder named in a hint is no path of a reader's machine
            "warnings": [w.replace(str(work), "WORK") for w in card["warnings"]],
            "n_test": len(data_test),
        }
        print(
            f"{labelled_session} {channels}: adapt's choice {methods['adapt_choice']['all']}, "
            f"network {methods['learned']['all']} ({seconds:.0f} s)",
            flush=True,
        )
    return out


#: issue 11's floors: (channel set, duration key, accuracy)
FLOORS = (("all", "2.0", 0.98), ("heated", "4.0", 0.90))


def floor_summary(results: list[dict[str, Any]]) -> dict[str, Any]:
    """Across the labelled sessions, per channel set and method: the min and median accuracy (all
    touches) at every duration, and for how many labelled sessions each floor holds."""
    out: dict[str, Any] = {}
    for channels in ("heated", "all"):
        methods = results[0][channels]["methods"]
        out[channels] = {}
        for method in methods:
            values = {k: [r[channels]["methods"][method]["all"][k] for r in results] for k in map(_key, DURATIONS)}
            entry: dict[str, Any] = {
                "min": {k: min(v) for k, v in values.items()},
                "median": {k: float(statistics.median(v)) for k, v in values.items()},
            }
            for ch, key, floor in FLOORS:
                if ch == channels:
                    held = [
                        r["labelled"] for r in results if r[channels]["methods"][method]["all"][key] >= floor - 1e-9
                    ]
                    entry[f"floor_{floor:g}_at_{key}_s"] = {"held": len(held), "of": len(results), "sessions": held}
            out[channels][method] = entry
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default=None, help="the thermal-robot folder")
    parser.add_argument("--label", default="R_1", help="labelled session(s), comma-separated (one run each)")
    parser.add_argument("--n-train", type=int, default=16000)
    parser.add_argument("--epochs", type=int, default=12)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--work", default=None, help="keep the runs here (default: a temporary folder)")
    parser.add_argument("--json", default=None, help="write the results here (after every labelled session)")
    parser.add_argument(
        "--reuse", action="store_true", help="with --work: keep the networks adapt trained there before (same settings)"
    )
    args = parser.parse_args(argv)
    data = robot_data(args.data)
    if not (data / "touches.csv").is_file():
        raise SystemExit(f"no recordings at {data} (give --data or set TACTILE_THERMAL_ROBOT)")
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.work) if args.work else Path(tmp)
        for session in args.label.split(","):
            results.append(run_session(data, session.strip(), work, args))
            summary = {
                "command": "python scripts/thermal_robot_protocol.py "
                + " ".join(a for a in (sys.argv[1:] if argv is None else argv) if not a.startswith("/")),
                "durations_s": list(DURATIONS),
                "sessions": results,
                "summary": floor_summary(results),
            }
            if args.json:  # after every session: a long run interrupted keeps what it measured
                atomic_write_json(args.json, summary)
    if len(results) > 1:
        across = floor_summary(results)
        at = ", ".join(map(_key, DURATIONS))
        print(f"\nacross {len(results)} labelled sessions (min / median at {at} s; floors held)")
        for channels, methods in across.items():
            for method, entry in methods.items():
                cells = " ".join(f"{entry['min'][k]:.3f}/{entry['median'][k]:.3f}" for k in map(_key, DURATIONS))
                held = [f"{k}: {v['held']}/{v['of']}" for k, v in entry.items() if k.startswith("floor")]
                print(f"  {channels:6s} {method:14s} {cells}  {' '.join(held)}")
    for r in results:
        for channels in ("heated", "all"):
            print(f"\n{r['labelled']} labelled, channels {channels}: accuracy at {', '.join(map(_key, DURATIONS))} s")
            for method, table in r[channels]["methods"].items():
                cells = "  ".join(
                    f"{g} " + "/".join(f"{table[g][_key(d)]:.2f}" for d in DURATIONS) for g in ("all", "M", "W", "CW")
                )
                if "leave_one_out" in table:  # the few-shot methods: their check on the labelled touches
                    cells += (
                        "  (leave-one-out "
                        + "/".join(f"{table['leave_one_out'][_key(d)]:.2f}" for d in DURATIONS)
                        + ")"
                    )
                print(f"  {method:12s} {cells}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
