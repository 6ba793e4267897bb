"""Two identical contacts - the case two orthogonal layers cannot pair - with and without diagonal strips.

Two identical spheres on distinct rows and columns light two rows and two columns; the two real
crossings and the two ghost crossings give the orthogonal pair the same readings. A diagonal layer
(``strips.geometry.layout = "diagonal"``) sees the real and the ghost crossings on different
diagonal strips. For each layout this script generates training frames (half of them identical
pairs), validation frames and held-out test frames of identical pairs (``strips16_twins``, another
seed), trains the layout's learned model, and reports on the test frames, per method
(``intersection``, ``projection`` - the refinement over every channel -, ``learned``), and the
classical methods on every layout (diagonal +45 and both, two-ended, 2 and 4 taps):

- ``pearson_r_mean``: the map's Pearson r against the true intersection map, mean over frames;
- ``ghost_energy``: the share of the reconstructed load (sum of the map) on the two ghost
  crossings, mean over frames whose contacts are more than a pitch apart in x and y (0: no ghosts;
  about 0.5: the two pairings cannot be told apart);
- ``ghost_to_real_median``: estimated pressure on the ghost crossings over that on the real ones.

    python scripts/twins_layouts.py --work data/twins --out results/twins_layouts

writes ``OUT.json``, ``OUT.md`` (the table) and ``OUT.png`` (ghost energy per method and layout, and
one test frame's maps).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from synth.dataset import generate
from synth.io import atomic_write_json, atomic_write_text
from synth.scene import Scene, load_scene
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.sweep import point_scene
from tactile_learn.tasks import get_task
from tactile_learn.tasks.strips import crossing_pressure, distinct_crossings, ghost_energy, ghost_to_real

LAYOUTS = {"orthogonal": {}, "diagonal": {"strips.geometry.layout": "diagonal"}}
#: every layout, classical methods only (the second table)
ALL_LAYOUTS = {
    "orthogonal": {},
    "diagonal +45": {"strips.geometry.layout": "diagonal"},
    "diagonal both": {"strips.geometry.layout": "diagonal", "strips.geometry.diagonals": "both"},
    "two_ended": {"strips.geometry.layout": "two_ended"},
    "taps 2": {"strips.geometry.layout": "taps", "strips.geometry.taps": 2},
    "taps 4": {"strips.geometry.layout": "taps", "strips.geometry.taps": 4},
}
SEEDS = {"train": 101, "val": 102, "test": 103}


def scenes(layout: str) -> tuple[Scene, Scene]:
    """(training scene: half the frames identical pairs; test scene: identical pairs only)."""
    values = LAYOUTS[layout]
    test = load_scene("strips16_twins")
    train = point_scene(test, {**values, "strips.stimuli.twin_fraction": 0.5})
    return train, point_scene(test, values) if values else test


def run_layout(layout: str, work: Path, args: argparse.Namespace) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    from tactile_learn.export import export
    from tactile_learn.train import TrainConfig, train

    train_scene, test_scene = scenes(layout)
    folder = work / layout
    generate(train_scene, args.train_n, SEEDS["train"], folder / "train")
    generate(train_scene, args.val_n, SEEDS["val"], folder / "val")
    generate(test_scene, args.test_n, SEEDS["test"], folder / "test")
    run = folder / "run"
    if not (run / "model.pt").is_file():
        config = TrainConfig(
            task="strips",
            data=str(folder / "train"),
            val=str(folder / "val"),
            out=str(run),
            size="small",
            epochs=args.epochs,
            batch_size=args.batch_size,
            threads=args.threads,
            seed=0,
        )
        train(config, resume=(run / "checkpoint.pt").is_file(), progress=False)
    model = folder / "model.onnx"
    export(run, model, name=f"twins-{layout}")
    task = get_task("strips")
    data = task.load_eval_data(folder / "test")
    pitch = test_scene.sensor.geometry.pitch_mm
    apart = distinct_crossings(data.extra, pitch)
    rows: dict[str, Any] = {}
    maps: dict[str, np.ndarray] = {}
    for name in ("intersection", "projection", str(model)):
        est = resolve_method("strips", name, test_scene)
        pred = est.predict(data.inputs)
        label = "learned" if name.endswith(".onnx") else name
        r = pearson_per_frame(pred, data.truth["pressure"])
        picked = {k: v[apart] for k, v in data.extra.items()}
        ghosts = ghost_energy(pred[apart], picked, pitch)
        truth_ghosts = ghost_energy(data.truth["pressure"][apart], picked, pitch)
        real, ghost = crossing_pressure(pred[apart], picked, pitch)
        rows[label] = {
            "pearson_r_mean": float(np.nanmean(r)),
            "ghost_energy_mean": float(ghosts.mean()),
            "ghost_energy_truth_mean": float(truth_ghosts.mean()),
            "frames": len(pred),
            "frames_apart": int(apart.sum()),
            "ghost_to_real_median": float(np.median(ghost_to_real(real, ghost))),
        }
        maps[label] = pred
    maps["truth"] = data.truth["pressure"]
    result = {
        "layout": layout,
        "wires": test_scene.sensor.wire_count(),
        "train_frames": args.train_n,
        "test": {"frames": len(data), "seed": SEEDS["test"], "scene": test_scene.name},
        "methods": rows,
    }
    return result, {k: v[apart] for k, v in maps.items()}


def classical_rows(work: Path, n: int) -> list[dict[str, Any]]:
    """The classical methods on every layout's held-out identical pairs (same contacts: same seed)."""
    twins = load_scene("strips16_twins")
    rows = []
    for label, values in ALL_LAYOUTS.items():
        scene = point_scene(twins, values) if values else twins
        folder = work / "classical" / label.replace(" ", "_")
        generate(scene, n, SEEDS["test"], folder)
        data = get_task("strips").load_eval_data(folder)
        pitch = scene.sensor.geometry.pitch_mm
        apart = distinct_crossings(data.extra, pitch)
        picked = {k: v[apart] for k, v in data.extra.items()}
        for name in ("intersection", "projection"):
            pred = resolve_method("strips", name, scene).predict(data.inputs)
            real, ghost = crossing_pressure(pred[apart], picked, pitch)
            rows.append(
                {
                    "layout": label,
                    "wires": scene.sensor.wire_count(),
                    "method": name,
                    "pearson_r_mean": float(np.nanmean(pearson_per_frame(pred, data.truth["pressure"]))),
                    "ghost_energy_mean": float(ghost_energy(pred[apart], picked, pitch).mean()),
                    "ghost_to_real_median": float(np.median(ghost_to_real(real, ghost))),
                }
            )
    return rows


def classical_table(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| layout | wires | method | r (mean) | ghost energy | ghost / real (median) |",
        "|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {r['layout']} | {r['wires']} | {r['method']} | {r['pearson_r_mean']:.3f} | "
        f"{r['ghost_energy_mean']:.3f} | {r['ghost_to_real_median']:.3f} |"
        for r in rows
    ]
    return "\n".join(lines) + "\n"


def table(results: list[dict[str, Any]]) -> str:
    lines = [
        "| layout | wires | method | r (mean) | ghost energy | ghost / real (median) |",
        "|---|---|---|---|---|---|",
    ]
    for res in results:
        for name, row in res["methods"].items():
            lines.append(
                f"| {res['layout']} | {res['wires']} | {name} | {row['pearson_r_mean']:.3f} | "
                f"{row['ghost_energy_mean']:.3f} | {row['ghost_to_real_median']:.3f} |"
            )
    truth = results[0]["methods"]["intersection"]["ghost_energy_truth_mean"]
    lines.append("")
    lines.append(f"Ghost energy of the true maps: {truth:.3f} (the cover spreads a little load onto the ghost cells).")
    return "\n".join(lines) + "\n"


def plot(results: list[dict[str, Any]], maps: dict[str, dict[str, np.ndarray]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tactile_learn.bench_report import save_figure

    methods = list(results[0]["methods"])
    fig = plt.figure(figsize=(12, 5.5))
    ax = fig.add_subplot(1, 3, 1)
    width = 0.38
    for k, res in enumerate(results):
        values = [res["methods"][m]["ghost_energy_mean"] for m in methods]
        ax.bar(
            np.arange(len(methods)) + (k - 0.5) * width, values, width, label=f"{res['layout']} ({res['wires']} wires)"
        )
    ax.axhline(results[0]["methods"]["intersection"]["ghost_energy_truth_mean"], color="k", ls=":", label="true maps")
    ax.set_xticks(np.arange(len(methods)), methods)
    ax.set(ylabel="share of the map's load on the ghost crossings", title="two identical contacts")
    ax.legend(fontsize=8)
    frame = 0
    panels = [("truth", "orthogonal", "truth")] + [
        (m, layout, f"{layout}: {m}") for layout in ("orthogonal", "diagonal") for m in ("projection", "learned")
    ]
    vmax = float(maps["orthogonal"]["truth"][frame].max())
    for k, (method, layout, title) in enumerate(panels):
        sub = fig.add_subplot(2, 6, [3, 4, 5, 9, 10][k] + (1 if k >= 3 else 0))
        sub.imshow(maps[layout][method][frame], vmin=0, vmax=vmax, cmap="viridis", origin="lower")
        sub.set_title(title, fontsize=8)
        sub.set_xticks([])
        sub.set_yticks([])
    fig.tight_layout()
    save_figure(fig, path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--work", default="data/twins", help="datasets and training runs")
    parser.add_argument("--out", default="results/twins_layouts", help="OUT.json, OUT.md, OUT.png")
    parser.add_argument("--train-n", type=int, default=6000)
    parser.add_argument("--val-n", type=int, default=500)
    parser.add_argument("--test-n", type=int, default=1000)
    parser.add_argument("--epochs", type=int, default=8)
    parser.add_argument("--batch-size", type=int, default=128)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args(argv)
    work = Path(args.work)
    results, maps = [], {}
    for layout in LAYOUTS:
        res, layout_maps = run_layout(layout, work, args)
        results.append(res)
        maps[layout] = layout_maps
        print(json.dumps(res["methods"], indent=1), flush=True)
    classical = classical_rows(work, args.test_n)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(
        out.with_suffix(".json"), {"command": " ".join(sys.argv), "results": results, "classical_layouts": classical}
    )
    text = (
        table(results) + "\nEvery layout, classical methods, the same held-out frames:\n\n" + classical_table(classical)
    )
    atomic_write_text(out.with_suffix(".md"), text)
    plot(results, maps, out.with_suffix(".png"))
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
