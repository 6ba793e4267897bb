"""A learned "the rule is better here" flag for the default strip model (issue 12): a small MLP on the
32 readings predicts, frame by frame, whether the intersection rule's map beats ``strips16``'s by more
than :data:`LOSS_MARGIN` in r (a *losing* frame, as ``strips_unseen.py`` counts them); flagged frames get
the rule's map (the documented fallback). The readings-residual flag catches almost none of the losing
frames on rounds 2-5 (their maps are consistent with the readings); this one is trained on what loses.

Fixed before it was evaluated anywhere (docs/strips.md, "A learned fallback flag"):

- training frames: the router frames of ``scripts/strips_experts.py data`` (rounds 1-4's families, the
  training scenes they add, ``strips16_wide`` and two spheres, seeds 9501-9601), none of round 5 or the
  ood suite; 80 % to train, 20 % to choose the threshold;
- the threshold: the lowest probability at which the held-out fifth flags at most
  :data:`TWO_SPHERE_FLAG_SHARE` of its two-sphere frames and at most :data:`GENERAL_FLAG_SHARE` of its
  ``strips16_wide`` frames (two spheres carry the 0.96 floor with ~0.001 to spare);
- evaluated on two spheres (seed 3), ``strips16_mixed`` (seed 3), the ood suite and rounds 1-5 at seeds
  5151 and 6262, 600 frames a family; round 5 is the blind test.

    python scripts/strips_rule_guard.py train --data data/experts --out runs/rule-guard
    python scripts/strips_rule_guard.py eval --guard runs/rule-guard --json results/strips_experts/rule_guard.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from strips_experts import ROUTER_SEED, export_mlp, features, fit_mlp, load_mlp, per_family, read_frames

LOSS_MARGIN = 0.05  # as scripts/strips_unseen.py: a frame the model answers this far below the rule
TWO_SPHERE_FLAG_SHARE = 0.005
GENERAL_FLAG_SHARE = 0.05
SUITES = (
    "strips16_ood",
    "strips16_unseen",
    "strips16_unseen2",
    "strips16_unseen3",
    "strips16_unseen4",
    "strips16_unseen5",
)


def _methods() -> tuple[Any, Any]:
    from synth.scene import load_scene
    from tactile_learn.methods import resolve_method
    from tactile_learn.runtime import OnnxEstimator

    default = OnnxEstimator("models/strips16.onnx", threads=1).prepare()
    return default, resolve_method("strips", "intersection", load_scene("strips16"))


def losing(default_maps: np.ndarray, rule_maps: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Frames where the rule's r beats the default's by more than :data:`LOSS_MARGIN` (NaN r: -1)."""
    from tactile_learn.metrics import pearson_per_frame

    r_default = np.nan_to_num(pearson_per_frame(default_maps, truth), nan=-1.0)
    r_rule = np.nan_to_num(pearson_per_frame(rule_maps, truth), nan=-1.0)
    return r_rule > r_default + LOSS_MARGIN


def choose_threshold(p: np.ndarray, groups: np.ndarray) -> float:
    """The lowest threshold (on a grid of 1,000 quantiles of ``p`` and 1.0) at which the two-sphere
    frames (group 1) are flagged at most :data:`TWO_SPHERE_FLAG_SHARE` and the general frames (group 2)
    at most :data:`GENERAL_FLAG_SHARE` (a frame is flagged where ``p >= threshold``)."""
    candidates = np.unique(np.concatenate([np.quantile(p, np.linspace(0.0, 1.0, 1001)), [1.0]]))
    for t in candidates:
        spheres, general = p[groups == 1] >= t, p[groups == 2] >= t
        if (not spheres.size or spheres.mean() <= TWO_SPHERE_FLAG_SHARE) and (
            not general.size or general.mean() <= GENERAL_FLAG_SHARE
        ):
            return float(t)
    return float("inf")


def train(root: Path, out: Path, log: Any = print) -> dict[str, Any]:
    import torch

    default, rule = _methods()
    xs, ys, groups = [], [], []
    for folder in sorted(root.glob("*-router")):
        readings, truth = read_frames(folder)
        y = losing(default.predict(readings), rule.predict(readings), truth)
        group = 1 if folder.name == "scene-strips16-router" else 2 if folder.name == "scene-strips16_wide-router" else 0
        xs.append(features(readings))
        ys.append(y)
        groups.append(np.full(len(y), group))
        log(f"{folder.name}: losing {y.mean():.3f}")
    x, y, g = np.concatenate(xs), np.concatenate(ys).astype(np.float32), np.concatenate(groups)
    rng = np.random.default_rng(ROUTER_SEED + 7)
    order = rng.permutation(len(x))
    n_hold = len(x) // 5
    hold, fit = order[:n_hold], order[n_hold:]
    mean, std = x[fit].mean(axis=0), x[fit].std(axis=0) + 1e-6
    xt, yt = torch.from_numpy((x - mean) / std), torch.from_numpy(y)

    def report(epoch: int, _net: Any, loss: Any) -> None:
        if epoch % 20 == 19:
            log(f"epoch {epoch + 1}: loss {loss.item():.3f}")

    def loss_of(out: Any, target: Any) -> Any:
        return torch.nn.functional.binary_cross_entropy_with_logits(out[:, 0], target)

    net = fit_mlp(xt, yt, fit, rng, ROUTER_SEED + 7, 1, loss_of, report)
    with torch.no_grad():
        p_hold = torch.sigmoid(net(xt[hold])[:, 0]).numpy()
    threshold = choose_threshold(p_hold, g[hold])
    flagged = p_hold >= threshold
    lose = y[hold] > 0.5
    card = {
        "mean": mean.tolist(),
        "std": std.tolist(),
        "threshold": threshold,
        "held_out": {
            "frames": len(hold),
            "losing_share": float(lose.mean()),
            "flagged_share": float(flagged.mean()),
            "losing_flagged_share": float(flagged[lose].mean()),
            "two_spheres_flagged": float(flagged[g[hold] == 1].mean()),
            "general_flagged": float(flagged[g[hold] == 2].mean()),
        },
    }
    log(json.dumps(card["held_out"]))
    export_mlp(net, xt[:1], out / "guard.onnx", "logit")
    (out / "guard.json").write_text(json.dumps(card, indent=1))
    return card


class RuleGuard:
    """``strips16`` with the rule's map on the frames the flag calls losing."""

    def __init__(self, guard: Path) -> None:
        card, self.session = load_mlp(guard, "guard")
        self.threshold = float(card["threshold"])
        self.default, self.rule = _methods()

    def flags(self, readings: np.ndarray) -> np.ndarray:
        logit = self.session(readings)[:, 0]
        return 1.0 / (1.0 + np.exp(-logit.astype(np.float64))) >= self.threshold

    def predict(self, readings: np.ndarray) -> np.ndarray:
        maps = self.default.predict(readings)
        flagged = self.flags(readings)
        if flagged.any():
            maps[flagged] = self.rule.predict(readings[flagged])
        return maps


def evaluate(guard_dir: Path, n: int, seeds: list[int], log: Any = print) -> dict[str, Any]:
    from synth.scene import load_scene
    from tactile_learn.methods import resolve_method
    from tactile_learn.tasks import get_task

    task = get_task("strips")
    guard = RuleGuard(guard_dir)
    projection = resolve_method("strips", "projection", load_scene("strips16"))

    def one(data: Any) -> dict[str, float]:
        maps = {
            "strips16": guard.default.predict(data.inputs),
            "intersection": guard.rule.predict(data.inputs),
            "projection": projection.predict(data.inputs),
        }
        flagged = guard.flags(data.inputs)
        guarded = maps["strips16"].copy()
        guarded[flagged] = maps["intersection"][flagged]
        maps["guarded"] = guarded
        lose = losing(maps["strips16"], maps["intersection"], data.truth["pressure"])
        row = {m: task.metrics(v, data)["pearson_r_mean"] for m, v in maps.items()}
        row["flagged_share"] = float(flagged.mean())
        row["losing_share"] = float(lose.mean())
        row["losing_flagged_share"] = float(flagged[lose].mean()) if lose.any() else float("nan")
        return row

    result: dict[str, Any] = {"threshold": guard.threshold, "sets": {}, "suites": {}}
    for name, folder in (("two_spheres", "data/strips16-test"), ("mixed", "data/mixed-test")):
        result["sets"][name] = one(task.load_eval_data(folder))
        log(name, {k: round(v, 4) for k, v in result["sets"][name].items()})
    for suite_name in SUITES:
        rows = per_family(suite_name, n, seeds, one)
        table = {}
        for fam, per_seed in rows.items():
            mean = {k: float(np.nanmean([r[k] for r in per_seed])) for k in per_seed[0]}
            best = [max(r["intersection"], r["projection"]) for r in per_seed]
            mean["margin_strips16"] = float(np.mean([r["strips16"] - b for r, b in zip(per_seed, best, strict=True)]))
            mean["margin_guarded"] = float(np.mean([r["guarded"] - b for r, b in zip(per_seed, best, strict=True)]))
            mean["below_strips16"] = float(max(r["strips16"] - b for r, b in zip(per_seed, best, strict=True)) < 0)
            mean["below_guarded"] = float(max(r["guarded"] - b for r, b in zip(per_seed, best, strict=True)) < 0)
            table[fam] = mean
        summary = {
            k: float(np.mean([t[k] for t in table.values()]))
            for k in ("margin_strips16", "margin_guarded", "flagged_share", "losing_flagged_share")
        }
        summary["families_below_strips16"] = int(sum(t["below_strips16"] for t in table.values()))
        summary["families_below_guarded"] = int(sum(t["below_guarded"] for t in table.values()))
        result["suites"][suite_name] = {"families": table, "summary": summary}
        log(suite_name, json.dumps({k: round(v, 4) for k, v in summary.items()}))
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("train")
    p.add_argument("--data", default="data/experts")
    p.add_argument("--out", default="runs/rule-guard")
    p = sub.add_parser("eval")
    p.add_argument("--guard", default="runs/rule-guard")
    p.add_argument("--seeds", type=int, nargs="+", default=[5151, 6262])
    p.add_argument("--n", type=int, default=600)
    p.add_argument("--json")
    args = parser.parse_args(argv)
    if args.command == "train":
        train(Path(args.data), Path(args.out))
    else:
        result = evaluate(Path(args.guard), args.n, args.seeds)
        if args.json:
            Path(args.json).write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
