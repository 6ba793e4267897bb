"""Does the readings residual tell a known object's frames from an unknown one's that a bundle routes wrongly?

A known-objects bundle (tactile_learn.known_objects) sends some frames of unknown objects to a specialist, and
they lose (docs/strips.md, "Known objects among unknown ones"). A second gate could refuse a specialist's map
that explains the readings worse than the default's. This measures whether that would separate the two: for
the frames a bundle sends to a specialist, per family, the specialist's and the default's per-frame r and
readings residual (``residual_rel``, tactile_learn.strips_consistency) on the same frames::

    python scripts/strips_bundle_residual.py runs/objects12-bundle/bundle.json --known strips16_unseen12 \\
        --unknown strips16_unseen11 strips16_ood --json results/strips_specialists12/bundle_residual.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import strips_unseen

from synth.suite import load_suite
from tactile_learn.known_objects import KnownObjects
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.strips_consistency import StripConsistency
from tactile_learn.suites import suite_eval_data


def sent_frames(bundle: KnownObjects, readings: np.ndarray, truth: np.ndarray) -> dict[str, Any] | None:
    """For the frames the bundle sends to a specialist: how many, the specialist's r minus the default's (mean),
    and both maps' residuals (median) with the median of their per-frame ratio; None if none is sent."""
    choice = bundle.router_.choose(readings, bundle.accept_)
    known = len(bundle.objects_)
    sent = choice < known
    if not sent.any():
        return None
    x, t, c = readings[sent], truth[sent], choice[sent]
    spec = np.empty((len(x), *truth.shape[1:]), dtype=np.float32)
    for k in np.unique(c):
        spec[c == k] = bundle.members_[int(k)].predict(x[c == k])
    default = bundle.members_[known].predict(x)
    consistency = StripConsistency(bundle.scene_)
    res_spec = consistency.residual(x, spec)["residual_rel"]
    res_default = consistency.residual(x, default)["residual_rel"]
    gain = np.asarray(pearson_per_frame(spec, t), dtype=np.float64) - np.asarray(pearson_per_frame(default, t))
    return {
        "sent": int(sent.sum()),
        "r_gain": float(np.nanmean(gain)),
        "residual_specialist": float(np.median(res_spec)),
        "residual_default": float(np.median(res_default)),
        "residual_ratio": float(np.median(res_spec / np.maximum(res_default, 1e-9))),
    }


def markdown(result: dict[str, Any]) -> str:
    lines = [
        f"# Frames a bundle sends to a specialist: r and readings residual (seed {result['seed']}, "
        f"{result['n']} frames a family)",
        "",
        f"`{result['command']}`",
        "",
        "| suite | family | known | sent | r: specialist - default | residual: specialist / default (medians) "
        "| median ratio |",
        "|---|---|---|---:|---:|---:|---:|",
    ]
    for row in result["rows"]:
        lines.append(
            f"| {row['suite']} | {row['family']} | {'yes' if row['known'] else 'no'} | {row['sent']} | "
            f"{row['r_gain']:+.3f} | {row['residual_specialist']:.4f} / {row['residual_default']:.4f} | "
            f"{row['residual_ratio']:.2f} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("bundle", help="a known-objects bundle (its folder or bundle.json)")
    parser.add_argument("--known", nargs="*", default=[], help="suites of the bundle's known objects")
    parser.add_argument("--unknown", nargs="*", default=[], help="suites of objects the bundle does not know")
    parser.add_argument("--seed", type=int, default=5151)
    parser.add_argument("--n", type=int, default=600, help="frames per family")
    parser.add_argument("--json", help="write the result here, and the Markdown table beside it (.md)")
    args = parser.parse_args(argv)
    if args.n < 1 or not (args.known or args.unknown):
        raise SystemExit("give --known or --unknown suites, and --n of at least 1")
    bundle = KnownObjects(args.bundle).prepare()
    rows = []
    for suites, known in ((args.known, True), (args.unknown, False)):
        for suite in suites:
            for family, data in suite_eval_data(load_suite(suite), args.n, args.seed).items():
                found = sent_frames(bundle, data.inputs, data.truth["pressure"])
                if found is not None:
                    rows.append({"suite": suite, "family": family, "known": known, **found})
    command = "python scripts/strips_bundle_residual.py " + " ".join(argv if argv is not None else sys.argv[1:])
    result = {"bundle": args.bundle, "seed": args.seed, "n": args.n, "rows": rows, "command": command}
    strips_unseen.report(result, markdown(result), args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
