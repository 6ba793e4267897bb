"""Objects learned from their readings (``tactile-learn learn-object``), each judged on its own family.

For every family of ``--suite`` with a learned object at ``LEARNED/FAMILY/specialist.onnx``: on the family's
frames at each of ``--seeds`` (drawn as ``strips_unseen.py`` draws them, so the same frames as a blind
judgement), r of the two classical rules, of every ``--models`` (e.g. the shipped default), of the learned
specialist and, where ``--reference`` names one (a path with ``{family}`` in it), of a specialist trained on the
family's true frames: what the readings hold when the simulator knows the object. Each model's margin is its
r minus the best rule's; ``share_of_reference`` = the learned margin over the reference's. A known-objects bundle
among ``--models`` also gets ``routed_to_own``: the share of the family's frames it sends to the specialist of
the same name. Writes the JSON and a Markdown table beside it::

    python scripts/strips_learned_objects.py --suite strips16_unseen12 --learned runs/learned12 \\
        --reference 'runs/s12spec-{family}/specialist.onnx' --models strips16 --seeds 5151 6262 --n 600 \\
        --json results/learned_objects/round12.json

``--guard-readings`` (a path with ``{family}`` in it: the readings each object was learned from) adds a
label-free check per object: the specialist's readings residual (its map pushed back through the sensor model)
on its own readings over that on its rendered validation frames, and the share of its readings its card's
threshold flags. A wrong template might show as a specialist that explains its own object's readings worse
than the frames it was trained on (docs/strips.md measures whether it does).

Without ``--learned`` every family is judged with ``--models`` only: e.g. a known-objects bundle of learned
objects (``tactile-learn objects``; a bundle folder is a method) on a round none of them was learned from.
The learned objects must have been fitted on frames drawn at other seeds (``object.json`` says which readings).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from synth.dataset import load_arrays
from synth.io import atomic_write_json, atomic_write_text
from synth.suite import Suite, load_suite
from tactile_learn.known_objects import KnownObjects
from tactile_learn.learned_objects import RENDERED_VAL
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.object_frames import readable_object_frames
from tactile_learn.suites import suite_eval_data

CLASSICAL = ("intersection", "projection")


def own_readings_check(specialist: Path, readings: np.ndarray, suite: Suite, frames: int) -> dict[str, float]:
    """The label-free check of a learned object (module docstring): its specialist's median readings residual on
    the first ``frames`` usable frames of the object's own ``readings`` and on its rendered validation frames."""
    from tactile_learn.strips_guard import CheckedStripModel

    own, _ = readable_object_frames(readings, suite.base.sensor)
    model = CheckedStripModel(specialist, scene=suite.base).prepare()
    on_own = model.check(own[:frames])
    rendered = load_arrays(specialist.parent / RENDERED_VAL, ["readings"])["readings"]
    on_rendered = model.check(rendered)
    own_median, rendered_median = float(np.median(on_own["residual"])), float(np.median(on_rendered["residual"]))
    return {
        "residual_own": own_median,
        "residual_rendered": rendered_median,
        "residual_ratio": own_median / rendered_median,
        "flagged_own": float(np.mean(on_own["flagged"])),
        "frames": int(min(frames, len(own))),
    }


def judge(
    suite: Suite,
    learned: Path | None,
    models: list[str],
    reference: str | None,
    seeds: list[int],
    n: int,
    log: Any = print,
    guard_readings: str | None = None,
    guard_frames: int = 1500,
) -> dict[str, Any]:
    """Every family with a learned object (or, with ``learned=None``, every family: ``models`` only); with
    ``guard_readings`` (a path with ``{family}``), each learned object's label-free check as well."""
    if learned is None:
        found: dict[str, Path | None] = {f.name: None for f in suite.families}
    else:
        found = {f.name: learned / f.name / "specialist.onnx" for f in suite.families}
        found = {fam: path for fam, path in found.items() if path is not None and path.is_file()}
        if not found:
            raise SystemExit(f"{learned}: no FAMILY/specialist.onnx for any family of {suite.name}")
    shared = {name: resolve_method("strips", name, suite.base, threads=1) for name in [*CLASSICAL, *models]}
    frames = {seed: suite_eval_data(suite, n, seed) for seed in seeds}
    families: dict[str, Any] = {}
    for fam, path in found.items():
        methods = dict(shared)
        if path is not None:
            methods["learned"] = resolve_method("strips", str(path), suite.base, threads=1)
        ref_path = Path(reference.format(family=fam)) if reference else None
        if ref_path is not None and ref_path.is_file():
            methods["reference"] = resolve_method("strips", str(ref_path), suite.base, threads=1)
        r: dict[str, list[float]] = {name: [] for name in methods}
        routed: dict[str, list[float]] = {}
        for seed in seeds:
            data = frames[seed][fam]
            for name, method in methods.items():
                r[name].append(
                    float(np.nanmean(pearson_per_frame(method.predict(data.inputs), data.truth["pressure"])))
                )
                if isinstance(method, KnownObjects):  # a bundle: how many of the family's frames reach its own
                    routed.setdefault(name, []).append(float(np.mean(method.route(data.inputs) == fam)))
        best_rule = max(CLASSICAL, key=lambda c: np.mean(r[c]))
        margins = {
            name: [a - b for a, b in zip(r[name], r[best_rule], strict=True)]
            for name in methods
            if name not in CLASSICAL
        }
        record_path = path.parent / "object.json" if path is not None else None
        record = json.loads(record_path.read_text()) if record_path is not None and record_path.is_file() else {}
        families[fam] = {
            "best_rule": best_rule,
            "r": {name: float(np.mean(v)) for name, v in r.items()},
            "margin": {name: float(np.mean(v)) for name, v in margins.items()},
            "margin_per_seed": margins,
            "fit_residual_median": record.get("fit", {}).get("residual_median"),
            "routed_to_own": {name: float(np.mean(v)) for name, v in routed.items()},
            "readings": record.get("command"),
        }
        if guard_readings is not None and path is not None:
            own = load_arrays(guard_readings.format(family=fam), ["readings"])["readings"]
            families[fam]["own_readings_check"] = own_readings_check(path, own, suite, guard_frames)
        m = families[fam]["margin"]
        log(
            f"{fam}: best rule r {families[fam]['r'][best_rule]:.3f}; "
            + ", ".join(f"{k} {v:+.3f}" for k, v in m.items())
        )
    names = [k for k in families[next(iter(families))]["margin"]]
    summary: dict[str, Any] = {}
    for name in names:
        values = [f["margin"][name] for f in families.values() if name in f["margin"]]
        below = [fam for fam, f in families.items() if name in f["margin"] and max(f["margin_per_seed"][name]) < 0]
        summary[name] = {"mean_margin": float(np.mean(values)), "families": len(values), "below_rule": below}
    with_ref = [f for f in families.values() if "reference" in f["margin"] and "learned" in f["margin"]]
    if with_ref:
        learned_gain = float(np.mean([f["margin"]["learned"] for f in with_ref]))
        reference_gain = float(np.mean([f["margin"]["reference"] for f in with_ref]))
        summary["share_of_reference"] = learned_gain / reference_gain if reference_gain > 0 else float("nan")
    return {
        "suite": suite.name,
        "learned": str(learned),
        "seeds": seeds,
        "frames_per_family": n,
        "summary": summary,
        "families": families,
    }


def markdown(result: dict[str, Any]) -> str:
    fams = result["families"]
    names = list(next(iter(fams.values()))["margin"])
    lines = [
        f"Margin over the best rule, {result['suite']}, seeds {result['seeds']}, "
        f"{result['frames_per_family']} frames a family",
        "",
        "| family | best rule r | " + " | ".join(names) + " | fit residual | own / rendered residual |",
        "|---|---:|" + "---:|" * len(names) + "---:|---:|",
    ]
    for fam, f in fams.items():
        cells = [f"{f['margin'][n]:+.3f}" if n in f["margin"] else "" for n in names]
        res = f["fit_residual_median"]
        check = f.get("own_readings_check")
        ratio = "" if check is None else f"{check['residual_ratio']:.2f} ({100 * check['flagged_own']:.0f} % flagged)"
        lines.append(
            f"| {fam} | {f['r'][f['best_rule']]:.3f} | "
            + " | ".join(cells)
            + f" | {'' if res is None else f'{res:.3f}'} | {ratio} |"
        )
    s = result["summary"]
    cells = [f"**{s[n]['mean_margin']:+.4f}** ({len(s[n]['below_rule'])})" for n in names]
    lines.append("| **mean** (below the rule) | | " + " | ".join(cells) + " | |")
    if "share_of_reference" in s:
        lines += [
            "",
            f"The learned specialists' mean margin is {100 * s['share_of_reference']:.0f} % of the references'.",
        ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--suite", required=True)
    parser.add_argument("--learned", default=None, help="folder of FAMILY/ learned objects (none: --models only)")
    parser.add_argument("--models", nargs="*", default=["strips16"], help="models judged beside (default strips16)")
    parser.add_argument("--reference", default=None, help="a specialist per family: a path with {family}")
    parser.add_argument("--seeds", type=int, nargs="+", default=[5151, 6262])
    parser.add_argument("--n", type=int, default=600)
    parser.add_argument("--guard-readings", default=None, help="each object's own readings: a path with {family}")
    parser.add_argument("--guard-frames", type=int, default=1500, help="own frames the check reads (default 1500)")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    learned = Path(args.learned) if args.learned else None
    result = judge(
        load_suite(args.suite),
        learned,
        args.models,
        args.reference,
        args.seeds,
        args.n,
        guard_readings=args.guard_readings,
        guard_frames=args.guard_frames,
    )
    table = markdown(result)
    print(table)
    if args.json:
        atomic_write_json(args.json, result)
        atomic_write_text(Path(args.json).with_suffix(".md"), table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
