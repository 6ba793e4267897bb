"""A hard-routed mixture of strip experts (issue 12's "next step" after the specialists): does a router
on the 32 readings that hands each frame to one of a few fine-tuned copies of ``strips16`` beat the
classical rules on shapes none of them was trained on?

The design is fixed in this file before any evaluation (see docs/strips.md, "A routed mixture of
experts"): three experts, each ``models/strips16.pt`` fine-tuned on one cluster of the families that
rounds 1-4 of the unseen-shape audit defined (rings and discs, many small contacts, edges and bars)
plus the general training scene; the default ``strips16`` is the fourth choice. The router is a small
MLP on the readings, trained to pick, frame by frame, the expert with the highest r on frames none of
the experts trained on (an expert must beat the default by :data:`ROUTE_MARGIN` to be the label), and
at run time a frame goes to an expert only where the router gives it at least :data:`ROUTE_PROBABILITY`.
Round 5 (``strips16_unseen5``, committed before this file) is the blind test; the ood suite stays out of
every training set.

    python scripts/strips_experts.py data --out data/experts            # the experts' and router's frames
    # each expert E (rings_discs, many_small, edges_bars): the command `plan` prints
    python scripts/strips_experts.py plan --data data/experts --runs runs
    python scripts/strips_experts.py router --data data/experts --runs runs --out runs/router
    python scripts/strips_experts.py eval --runs runs --router runs/router --json results/strips_experts.json
    # the longer variant: the same with --long before the command (runs/expert-long-NAME)
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from synth.dataset import generate
from synth.scene import load_scene
from synth.suite import load_suite
from tactile_learn.train_router import fit_mlp

#: the experts: (suite, family) pairs of rounds 1-4 and training scenes, grouped by the physical kind
#: of contact; families of rounds 1-4 in no cluster (knuckles, a stylus, a feather touch, a pinch, a
#: rolling thumb, a palm) train no expert and are router frames only
CLUSTERS: dict[str, list[tuple[str, str]]] = {
    "rings_discs": [
        ("strips16_unseen", "bottle_cap"),
        ("strips16_unseen", "thin_rim"),
        ("strips16_unseen", "tabbed_coin_cell"),
        ("strips16_unseen", "broad_fingertip"),
        ("strips16_unseen2", "coin_off_centre"),
        ("strips16_unseen3", "espresso_cup_foot"),
        ("strips16_unseen4", "scissors_loops"),
        ("strips16_unseen4", "bead_loop"),
        ("strips16_unseen4", "watch_on_its_back"),
        ("strips16_unseen4", "spoon_bowl"),
        ("scene", "strips16_large_rings"),
    ],
    "many_small": [
        ("strips16_unseen", "five_fingertips"),
        ("strips16_unseen2", "lego_2x4"),
        ("strips16_unseen2", "lego_2x2_square"),
        ("strips16_unseen2", "fingertips_along_row"),
        ("strips16_unseen2", "thumb_and_fingertips"),
        ("strips16_unseen2", "fork_tines"),
        ("strips16_unseen2", "dip8_chip"),
        ("strips16_unseen3", "bottle_base_feet"),
        ("strips16_unseen3", "tripod_feet"),
        ("strips16_unseen3", "shoe_sole_nubs"),
        ("strips16_unseen3", "comb_teeth"),
        ("strips16_unseen3", "toy_car_wheels"),
        ("strips16_unseen3", "cat_paw"),
        ("strips16_unseen3", "die_face"),
        ("strips16_unseen4", "ball_chain"),
        ("strips16_unseen4", "hairbrush_pins"),
        ("scene", "strips16_five_circle"),
        ("scene", "strips16_five_quincunx"),
    ],
    "edges_bars": [
        ("strips16_unseen", "card_edge_along_strip"),
        ("strips16_unseen", "pen_across"),
        ("strips16_unseen", "flat_bar"),
        ("strips16_unseen2", "cross_bracket"),
        ("strips16_unseen2", "angle_bracket"),
        ("strips16_unseen2", "chopsticks"),
        ("strips16_unseen3", "key_teeth"),
        ("strips16_unseen3", "hex_key"),
        ("strips16_unseen3", "can_on_side"),
        ("strips16_unseen3", "ribbed_grip_pad"),
        ("strips16_unseen4", "aa_cells_side_by_side"),
        ("strips16_unseen4", "usb_plug_end_on"),
        ("strips16_unseen4", "card_corner"),
        ("strips16_unseen4", "ruler_edge"),
        ("strips16_unseen4", "house_key_flat"),
    ],
}
#: round 1-4 families in no cluster: router frames only
UNCLUSTERED: list[tuple[str, str]] = [
    ("strips16_unseen", "knuckle"),
    ("strips16_unseen", "stylus"),
    ("strips16_unseen", "feather_touch"),
    ("strips16_unseen", "heavy_pad"),
    ("strips16_unseen", "two_knuckles"),
    ("strips16_unseen2", "pinch_along_column"),
    ("strips16_unseen2", "rolling_thumb"),
    ("strips16_unseen4", "palm_heel_and_thumb"),
]
#: each expert's validation family (the best epoch is kept on it): its cluster's worst loser
VALIDATION = {
    "rings_discs": ("strips16_unseen3", "espresso_cup_foot"),
    "many_small": ("strips16_unseen4", "hairbrush_pins"),
    "edges_bars": ("strips16_unseen4", "card_corner"),
}
GENERAL = ("scene", "strips16_wide")  # the default's own training scene, mixed into every expert's data
TWO_SPHERES = ("scene", "strips16")
FRAMES_PER_FAMILY = 2000
GENERAL_FRAMES = 12000
ROUTER_FRAMES_PER_FAMILY = 400
ROUTER_GENERAL_FRAMES = 6000
TRAIN_SEED, VAL_SEED, ROUTER_SEED = 9301, 9401, 9501
EPOCHS, LR = 6, 3e-4
#: a second, longer training of the same experts (the specialists were still improving at 8-32 epochs),
#: declared before either was evaluated: runs/expert-long-NAME, the router trained on them alike
LONG_EPOCHS = 24
ROUTE_MARGIN = 0.02  # an expert is a frame's label only where its r beats the default's by this much
ROUTE_PROBABILITY = 0.5  # ... and a frame goes to it only where the router is at least this sure
EXPERTS = tuple(CLUSTERS)
CHOICES = ("default", *EXPERTS)


def _source_scene(source: tuple[str, str]) -> Any:
    kind, name = source
    return load_scene(name) if kind == "scene" else load_suite(kind).family(name).scene


def _folder(root: Path, source: tuple[str, str], part: str) -> Path:
    return root / f"{source[0]}-{source[1]}-{part}"


def _write(source: tuple[str, str], n: int, seed: int, out: Path) -> Path:
    if (out / "manifest.json").exists():
        return out
    generate(_source_scene(source), n, seed, out)
    return out


def write_data(root: Path, log: Any = print) -> None:
    """Every expert's training frames, its validation family and the router's frames (other seeds)."""
    start = time.perf_counter()
    sources = [s for members in CLUSTERS.values() for s in members]
    for i, source in enumerate(sources):
        _write(source, FRAMES_PER_FAMILY, TRAIN_SEED + i, _folder(root, source, "train"))
    _write(GENERAL, GENERAL_FRAMES, TRAIN_SEED + 100, _folder(root, GENERAL, "train"))
    for i, source in enumerate(VALIDATION.values()):
        _write(source, 1000, VAL_SEED + i, _folder(root, source, "val"))
    for i, source in enumerate([*sources, *UNCLUSTERED]):
        _write(source, ROUTER_FRAMES_PER_FAMILY, ROUTER_SEED + i, _folder(root, source, "router"))
    _write(GENERAL, ROUTER_GENERAL_FRAMES, ROUTER_SEED + 100, _folder(root, GENERAL, "router"))
    _write(TWO_SPHERES, 2000, ROUTER_SEED + 101, _folder(root, TWO_SPHERES, "router"))
    log(f"data in {time.perf_counter() - start:.0f} s")


def plan(root: Path, runs: Path, long: bool = False) -> list[str]:
    """The training and export command of every expert (``long``: the :data:`LONG_EPOCHS` variant)."""
    lines = []
    for name, members in CLUSTERS.items():
        # the validation family's frames first: training takes its scene from the first folder, and the
        # validation set must be of that scene
        ordered = [VALIDATION[name], *(s for s in members if s != VALIDATION[name]), GENERAL]
        data = " ".join(str(_folder(root, s, "train")) for s in ordered)
        run = runs / f"expert-{'long-' if long else ''}{name}"
        lines.append(
            f"tactile-learn train --task strips --data {data} --val {_folder(root, VALIDATION[name], 'val')} "
            f"--out {run} --init models/strips16.pt --lr {LR} --epochs {LONG_EPOCHS if long else EPOCHS} --threads 1 "
            "--quiet && "
            f"tactile-learn export {run} --out {run}/model.onnx --overwrite"
        )
    return lines


def _estimators(runs: Path, long: bool = False) -> dict[str, Any]:
    from tactile_learn.runtime import OnnxEstimator

    found = {"default": OnnxEstimator("models/strips16.onnx", threads=1).prepare()}
    for name in EXPERTS:
        run = runs / f"expert-{'long-' if long else ''}{name}"
        found[name] = OnnxEstimator(run / "model.onnx", threads=1).prepare()
    return found


def _per_frame_r(estimators: dict[str, Any], readings: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(B, len(CHOICES)) per-frame Pearson r of every choice."""
    from tactile_learn.metrics import pearson_per_frame

    return np.stack([pearson_per_frame(estimators[c].predict(readings), truth) for c in CHOICES], axis=1)


def read_frames(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    from synth.dataset import load_arrays

    ds = load_arrays(folder, ["readings", "pressure"])
    return np.asarray(ds["readings"], dtype=np.float32), np.asarray(ds["pressure"], dtype=np.float32)


def features(readings: np.ndarray) -> np.ndarray:
    """The router's input: the readings above the readout's offset, as a share of the frame's total,
    with the log of the total (a frame's shape, then its load)."""
    above = np.clip(readings - 0.3, 0.0, None)
    total = above.sum(axis=1, keepdims=True)
    share = above / np.maximum(total, 1e-6)
    return np.concatenate([share * 16.0, np.log(np.maximum(total, 1e-4))], axis=1).astype(np.float32)


def export_mlp(net: Any, example: Any, path: Path, output: str) -> None:
    """``net`` as ONNX by the package's exporter (any batch): input ``features``, output ``output``."""
    from tactile_learn.export import to_onnx

    path.parent.mkdir(parents=True, exist_ok=True)
    to_onnx(net, example, path, "features", output, {"script": "scripts/strips_experts.py"})


def train_router(root: Path, runs: Path, out: Path, long: bool = False, log: Any = print) -> dict[str, Any]:
    import torch

    estimators = _estimators(runs, long)
    folders = sorted(root.glob("*-router"))
    xs, labels = [], []
    for folder in folders:
        readings, truth = read_frames(folder)
        r = np.nan_to_num(_per_frame_r(estimators, readings, truth), nan=-1.0)
        best = r.argmax(axis=1)
        label = np.where(r[np.arange(len(r)), best] >= r[:, 0] + ROUTE_MARGIN, best, 0)
        xs.append(features(readings))
        labels.append(label)
        log(f"{folder.name}: labels {np.bincount(label, minlength=len(CHOICES)).tolist()}")
    x = np.concatenate(xs)
    y = np.concatenate(labels)
    rng = np.random.default_rng(ROUTER_SEED)
    order = rng.permutation(len(x))
    n_val = len(x) // 10
    val, train = order[:n_val], order[n_val:]
    mean, std = x[train].mean(axis=0), x[train].std(axis=0) + 1e-6
    xt = torch.from_numpy((x - mean) / std)
    yt = torch.from_numpy(y.astype(np.int64))

    def report(epoch: int, net: Any, loss: Any) -> None:
        if epoch % 10 == 9:
            net.eval()
            with torch.no_grad():
                acc = float((net(xt[val]).argmax(1) == yt[val]).float().mean())
            log(f"router epoch {epoch + 1}: loss {float(loss):.3f}, val accuracy {acc:.3f}")

    net = fit_mlp(xt, yt, train, rng, ROUTER_SEED, len(CHOICES), torch.nn.functional.cross_entropy, report)
    export_mlp(net, xt[:1], out / "router.onnx", "logits")
    card = {"choices": list(CHOICES), "mean": mean.tolist(), "std": std.tolist(), "labels": np.bincount(y).tolist()}
    (out / "router.json").write_text(json.dumps(card, indent=1))
    return card


def load_mlp(folder: Path, stem: str) -> tuple[dict[str, Any], Any]:
    """An exported MLP (``folder/stem.onnx``, one thread) and its card (``folder/stem.json``: the
    features' ``mean`` and ``std``): the card and ``run(readings) -> outputs`` on :func:`features`."""
    import onnxruntime as ort

    card = json.loads((folder / f"{stem}.json").read_text())
    mean, std = np.asarray(card["mean"], np.float32), np.asarray(card["std"], np.float32)
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    session = ort.InferenceSession(str(folder / f"{stem}.onnx"), options, providers=["CPUExecutionProvider"])

    def run(readings: np.ndarray) -> np.ndarray:
        return np.asarray(session.run(None, {"features": (features(readings) - mean) / std})[0])

    return card, run


def per_family(suite_name: str, n: int, seeds: list[int], one: Any) -> dict[str, list[Any]]:
    """``one(data)`` of every family of the suite at every seed (``n`` fresh frames each): family ->
    the results in the order of ``seeds``."""
    from tactile_learn.suites import suite_eval_data

    suite = load_suite(suite_name)
    rows: dict[str, list[Any]] = {f.name: [] for f in suite.families}
    for seed in seeds:
        for fam, data in suite_eval_data(suite, n, seed).items():
            rows[fam].append(one(data))
    return rows


class RoutedStrips:
    """The mixture at run time: the router's choice per frame, then that expert on its frames."""

    def __init__(self, runs: Path, router: Path, probability: float = ROUTE_PROBABILITY, long: bool = False) -> None:
        self.estimators = _estimators(runs, long)
        _, self.router = load_mlp(router, "router")
        self.probability = probability

    def route(self, readings: np.ndarray) -> np.ndarray:
        logits = self.router(readings)
        p = np.exp(logits - logits.max(axis=1, keepdims=True))
        p /= p.sum(axis=1, keepdims=True)
        choice = p.argmax(axis=1)
        return np.where(p.max(axis=1) >= self.probability, choice, 0)

    def predict(self, readings: np.ndarray) -> np.ndarray:
        choice = self.route(readings)
        out = np.empty((len(readings), 16, 16), dtype=np.float32)
        for k, name in enumerate(CHOICES):
            mask = choice == k
            if mask.any():
                out[mask] = self.estimators[name].predict(readings[mask])
        return out


def evaluate(
    runs: Path, router: Path, n: int, seeds: list[int], long: bool = False, log: Any = print
) -> dict[str, Any]:
    from tactile_learn.methods import resolve_method
    from tactile_learn.suites import suite_eval_data
    from tactile_learn.tasks import get_task

    task = get_task("strips")
    routed = RoutedStrips(runs, router, long=long)
    base = load_scene("strips16")
    methods: dict[str, Any] = {
        "intersection": resolve_method("strips", "intersection", base),
        "projection": resolve_method("strips", "projection", base),
        "strips16": routed.estimators["default"],
        **{f"expert:{e}": routed.estimators[e] for e in EXPERTS},
        "routed": routed,
    }
    result: dict[str, Any] = {"sets": {}, "suites": {}}
    for name, folder in (("two_spheres", "data/strips16-test"), ("mixed", "data/mixed-test")):
        data = task.load_eval_data(folder)
        scores = {m: task.metrics(est.predict(data.inputs), data)["pearson_r_mean"] for m, est in methods.items()}
        result["sets"][name] = scores
        result["sets"][name]["routed_share"] = np.bincount(routed.route(data.inputs), minlength=len(CHOICES)).tolist()
        log(name, {k: round(v, 4) if isinstance(v, float) else v for k, v in result["sets"][name].items()})
    for suite_name in ("strips16_ood", "strips16_unseen", "strips16_unseen2", "strips16_unseen3", "strips16_unseen4",
                       "strips16_unseen5"):  # fmt: skip
        suite = load_suite(suite_name)
        families: dict[str, dict[str, Any]] = {fam.name: {m: [] for m in methods} for fam in suite.families}
        shares: dict[str, list[list[int]]] = {fam.name: [] for fam in suite.families}
        for seed in seeds:
            for fam, data in suite_eval_data(suite, n, seed).items():
                for m, est in methods.items():
                    families[fam][m].append(task.metrics(est.predict(data.inputs), data)["pearson_r_mean"])
                shares[fam].append(np.bincount(routed.route(data.inputs), minlength=len(CHOICES)).tolist())
        table = {}
        for fam, rows in families.items():
            means = {m: float(np.mean(v)) for m, v in rows.items()}
            best = max(means["intersection"], means["projection"])
            table[fam] = {
                "r": means,
                "margin": {m: means[m] - best for m in ("strips16", "routed", *[f"expert:{e}" for e in EXPERTS])},
                "margin_per_seed": {
                    m: [rows[m][i] - max(rows["intersection"][i], rows["projection"][i]) for i in range(len(seeds))]
                    for m in ("strips16", "routed")
                },
                "routed_share": np.sum(shares[fam], axis=0).tolist(),
            }
        summary = {
            m: {
                "mean_margin": float(np.mean([t["margin"][m] for t in table.values()])),
                "families_below": [f for f, t in table.items() if max(t["margin_per_seed"][m]) < 0],
            }
            for m in ("strips16", "routed")
        }
        result["suites"][suite_name] = {"families": table, "summary": summary}
        log(suite_name, json.dumps(summary))
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--long", action="store_true", help=f"the {LONG_EPOCHS}-epoch experts (runs/expert-long-NAME)")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("data")
    p.add_argument("--out", default="data/experts")
    p = sub.add_parser("plan")
    p.add_argument("--data", default="data/experts")
    p.add_argument("--runs", default="runs")
    p = sub.add_parser("router")
    p.add_argument("--data", default="data/experts")
    p.add_argument("--runs", default="runs")
    p.add_argument("--out", default="runs/router")
    p = sub.add_parser("eval")
    p.add_argument("--runs", default="runs")
    p.add_argument("--router", default="runs/router")
    p.add_argument("--seeds", type=int, nargs="+", default=[5151, 6262])
    p.add_argument("--n", type=int, default=600)
    p.add_argument("--json")
    args = parser.parse_args(argv)
    if args.command == "data":
        write_data(Path(args.out))
    elif args.command == "plan":
        print("\n".join(plan(Path(args.data), Path(args.runs), args.long)))
    elif args.command == "router":
        train_router(Path(args.data), Path(args.runs), Path(args.out), args.long)
    else:
        result = evaluate(Path(args.runs), Path(args.router), args.n, args.seeds, args.long)
        if args.json:
            Path(args.json).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
