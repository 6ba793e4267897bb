"""Why does a strip model lose an unseen family? Sweep one parameter across the training range's edge.

Each probe is a family of ``strips16_unseen`` with one parameter (or the contact count) set to a
ladder of values, some inside the training scene's range (``strips16_mixed``), some beyond it; at
every value the model's r against the best classical rule on the same fresh frames. A margin that
holds inside the training range and falls beyond it says the loss is a gap in the training
distribution; one that is negative inside too says it is not::

    python scripts/strips_unseen_probe.py --n 300 --seed 7777 --json results/strips_unseen_probe.json
"""

from __future__ import annotations

import argparse
import copy
import sys
from typing import Any

import numpy as np

from synth.io import atomic_write_json
from synth.scene import read_toml
from synth.suite import parse_suite
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.suites import suite_eval_data

CLASSICAL = ("intersection", "projection")

#: probe: (family of strips16_unseen, what is swept, values); "count" sets the contacts per frame,
#: any other name is a parameter of the family's (only) stimulus kind, set to a point range
PROBES: dict[str, tuple[str, str, tuple[float, ...]]] = {
    "punch_radius": ("bottle_cap", "radius_mm", (3.0, 4.5, 6.0, 7.0, 8.0, 9.0, 10.0)),
    "fingertip_count": ("five_fingertips", "count", (2, 3, 4, 5)),
    "blob_width": ("broad_fingertip", "width_mm", (2.0, 3.0, 4.0, 4.5, 5.0, 6.0, 7.0)),
    "rim_hole": ("thin_rim", "hole_fraction", (0.5, 0.7, 0.8, 0.86, 0.9, 0.93)),
}


def probe_suite(probe: str) -> dict[str, Any]:
    """A suite (as TOML data) of one family per value of the probe's ladder."""
    family_name, parameter, values = PROBES[probe]
    data, _ = read_toml("strips16_unseen", "suites", "suite")
    template = next(f for f in data["families"] if f["name"] == family_name)
    families = []
    for value in values:
        fam = copy.deepcopy(template)
        fam["name"] = f"{parameter}={value:g}"
        stimuli = fam["strips"]["stimuli"]
        if parameter == "count":
            stimuli["count"] = [int(value), int(value)]
        else:
            for kind in stimuli["kinds"]:
                kind[parameter] = [float(value), float(value)]
        families.append(fam)
    return {**data, "name": f"probe_{probe}", "families": families}


def run_probe(probe: str, models: list[str], n: int, seed: int) -> dict[str, Any]:
    suite = parse_suite(probe_suite(probe), f"probe {probe}")
    estimators = {m: resolve_method("strips", m, suite.base, threads=1) for m in [*CLASSICAL, *models]}
    rows: dict[str, Any] = {}
    for fam, data in suite_eval_data(suite, n, seed).items():
        truth = data.truth["pressure"]
        r = {m: float(np.nanmean(pearson_per_frame(e.predict(data.inputs), truth))) for m, e in estimators.items()}
        best = max(r[c] for c in CLASSICAL)
        rows[fam] = {"r": r, "margin": {m: r[m] - best for m in models}}
        margins = ", ".join(f"{m} {rows[fam]['margin'][m]:+.3f}" for m in models)
        print(f"{probe:16s} {fam:20s} best classical {best:.3f}  {margins}")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="*", default=["strips16", "strips16_small"])
    parser.add_argument("--probes", nargs="+", default=list(PROBES), choices=list(PROBES))
    parser.add_argument("--n", type=int, default=300, help="frames per value")
    parser.add_argument("--seed", type=int, default=7777)
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    result = {
        "command": "python scripts/strips_unseen_probe.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "seed": args.seed,
        "frames_per_value": args.n,
        "probes": {p: run_probe(p, args.models, args.n, args.seed) for p in args.probes},
    }
    if args.json:
        atomic_write_json(args.json, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
