"""Why does a strip model lose an unseen family? Sweep one parameter across the training range's edge.

Each probe is a family of an unseen-shape suite (``strips16_unseen``, ``_unseen2`` to ``_unseen5``) with one
parameter (or the contact count, or a parameter of the family's object) set to a ladder of values,
some inside the training scene's range, some beyond it; at every value the model's r against the best
classical rule on the same fresh frames. A margin that holds inside the training range and falls
beyond it says the loss is a gap in the training distribution; one that is negative inside too says
it is not::

    python scripts/strips_unseen_probe.py --n 300 --seed 7777 --json results/strips_unseen_probe.json
    python scripts/strips_unseen_probe.py --suite strips16_unseen2 strips16 --n 300 --seed 7777 \
        --json results/strips_unseen2_probe.json
    python scripts/strips_unseen_probe.py --suite strips16_unseen3 strips16 strips16_small --n 300 \
        --seed 7777 --json results/strips_unseen3_probe.json
    python scripts/strips_unseen_probe.py --suite strips16_unseen4 strips16 strips16_small --n 300 \
        --seed 7777 --json results/strips_unseen4_probe.json
    python scripts/strips_unseen_probe.py --suite strips16_unseen5 strips16 strips16_small --n 300 \
        --seed 7777 --json results/strips_unseen5_probe.json
"""

from __future__ import annotations

import argparse
import copy
import itertools
import sys
from typing import Any

import numpy as np

from synth.io import atomic_write_json
from synth.scene import Scene, load_scene, read_toml
from synth.suite import parse_suite
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.suites import suite_eval_data

CLASSICAL = ("intersection", "projection")

#: probe: (suite, family, what is swept, values, fixed); "count" sets the contacts per frame, "parts"
#: cuts the family's object down to its first parts (and their kinds), "margin_mm" sets the margin,
#: "object.NAME" a parameter of the family's object, any other name a parameter of every stimulus kind
#: of the family (a point range); ``fixed`` sets others so for every value
PROBES: dict[str, tuple[str, str, str, tuple[float, ...], dict[str, float]]] = {
    "punch_radius": ("strips16_unseen", "bottle_cap", "radius_mm", (3.0, 4.5, 6.0, 7.0, 8.0, 9.0, 10.0), {}),
    "fingertip_count": ("strips16_unseen", "five_fingertips", "count", (2, 3, 4, 5), {}),
    "blob_width": ("strips16_unseen", "broad_fingertip", "width_mm", (2.0, 3.0, 4.0, 4.5, 5.0, 6.0, 7.0), {}),
    "rim_hole": ("strips16_unseen", "thin_rim", "hole_fraction", (0.5, 0.7, 0.8, 0.86, 0.9, 0.93), {}),
    # round 2: a pushed coin's tilt from none (the punches training draws) to the rim lifting, and
    # its size at the family's tilts
    "coin_tilt": ("strips16_unseen2", "coin_off_centre", "tilt", (0.0, 0.25, 0.5, 0.75, 1.0), {}),
    "coin_radius": ("strips16_unseen2", "coin_off_centre", "radius_mm", (4.0, 6.0, 8.0, 10.0, 11.5, 13.0), {}),
    # the family's coins, centred from 8 mm of the edge (up to 5 mm of a coin off the array) to 14 (all on it)
    "coin_margin": ("strips16_unseen2", "coin_off_centre", "margin_mm", (8.0, 11.0, 14.0), {}),
    # studs square to the strips: one, two on a row, three (an L: its fourth corner is a ghost), four
    "square_studs": ("strips16_unseen2", "lego_2x2_square", "count", (1, 2, 3, 4), {}),
    # the square turned from square to the strips (every corner real and every ghost a corner) to a diamond
    "square_turn": (
        "strips16_unseen2",
        "lego_2x2_square",
        "object.rotation_deg",
        (0.0, 5.0, 10.0, 20.0, 30.0, 45.0),
        {},
    ),
    # two studs of the square turned from one row (no ghost) to a diagonal (the ghost case)
    "pair_turn": (
        "strips16_unseen2",
        "lego_2x2_square",
        "object.rotation_deg",
        (0.0, 10.0, 20.0, 30.0, 45.0),
        {"count": 2},
    ),
    "chip_pins": ("strips16_unseen2", "dip8_chip", "count", (2, 4, 6, 8), {}),
    "brick_studs": ("strips16_unseen2", "lego_2x4", "count", (2, 4, 6, 8), {}),
    # round 3: the cup's foot ring shrunk into the training rings' radii (up to 15 mm), at the family's
    # thin rims and at a thick one (hole 0.6, inside every training ring range); the rim thickened
    "cup_radius": ("strips16_unseen3", "espresso_cup_foot", "radius_mm", (6.0, 9.0, 12.0, 14.0, 15.5, 17.0, 18.5), {}),
    "cup_radius_thick": (
        "strips16_unseen3",
        "espresso_cup_foot",
        "radius_mm",
        (6.0, 9.0, 12.0, 14.0, 15.5, 17.0, 18.5),
        {"hole_fraction": 0.6},
    ),
    "cup_hole": ("strips16_unseen3", "espresso_cup_foot", "hole_fraction", (0.4, 0.6, 0.8, 0.87, 0.91), {}),
    # objects of many parts, from one part up to the family's count (the models trained on up to six)
    "sole_nubs": ("strips16_unseen3", "shoe_sole_nubs", "count", (1, 2, 4, 6, 8, 10, 12, 14), {}),
    "tripod_feet": ("strips16_unseen3", "tripod_feet", "count", (1, 2, 3), {}),
    "tripod_size": ("strips16_unseen3", "tripod_feet", "object.scale", (5.0, 7.0, 9.0, 11.5, 14.0), {}),
    "paw_toes": ("strips16_unseen3", "cat_paw", "count", (1, 2, 3, 4, 5), {}),
    "bottle_feet": ("strips16_unseen3", "bottle_base_feet", "count", (1, 2, 3, 4, 5), {}),
    # round 4: the watch's case alone (no straps, at most 8 mm of it off the array) from training's punch
    # radii (up to 15 mm) to the family's, and the family itself (straps on) over the same radii
    "watch_case_radius": (
        "strips16_unseen4",
        "watch_on_its_back",
        "radius_mm",
        (6.0, 9.0, 12.0, 15.0, 16.0, 17.5, 19.0),
        {"parts": 1, "margin_mm": 12.0},
    ),
    "watch_radius": (
        "strips16_unseen4",
        "watch_on_its_back",
        "radius_mm",
        (6.0, 9.0, 12.0, 15.0, 16.0, 17.5, 19.0),
        {},
    ),
    # many small contacts: pins and beads from one up to the family's count (training stops at ten)
    "brush_pins": ("strips16_unseen4", "hairbrush_pins", "count", (1, 2, 4, 6, 8, 10, 12, 14, 16), {}),
    "bead_count": ("strips16_unseen4", "bead_loop", "count", (1, 2, 4, 6, 8, 10, 13), {}),
    # the bead loop shrunk from the family's 16.5-18.5 mm radius until its beads touch (a ring)
    "bead_loop_radius": ("strips16_unseen4", "bead_loop", "object.scale", (6.0, 9.0, 12.0, 15.0, 17.5), {}),
    # a card's corner: its edges widened into training's block widths, and its tilt taken away
    "card_width": ("strips16_unseen4", "card_corner", "width_mm", (0.5, 0.8, 1.0, 1.5, 2.5, 4.0), {}),
    "card_tilt": ("strips16_unseen4", "card_corner", "tilt", (-1.0, -0.8, -0.6, -0.3, 0.0), {}),
    # round 5: the tumbler's rigid base from training's punch radii (up to 15 mm) to the family's, and
    # without its push off centre; the jar lid's rim and the tape roll's face from training's ring
    # radii (up to 19 mm) to the family's, and the lid's rim from thick to the family's thin one
    "tumbler_radius": (
        "strips16_unseen5",
        "tumbler_base",
        "radius_mm",
        (6.0, 9.0, 12.0, 15.0, 20.0, 25.0, 30.0, 34.0),
        {},
    ),
    "tumbler_tilt": ("strips16_unseen5", "tumbler_base", "tilt", (0.0, 0.3, 0.6), {}),
    "lid_radius": (
        "strips16_unseen5",
        "jar_lid_rim",
        "radius_mm",
        (8.0, 11.0, 14.0, 17.0, 19.0, 21.0, 23.0, 25.0, 27.0),
        {},
    ),
    "lid_hole": ("strips16_unseen5", "jar_lid_rim", "hole_fraction", (0.6, 0.75, 0.85, 0.9, 0.94), {}),
    "tape_radius": ("strips16_unseen5", "tape_roll_flat", "radius_mm", (9.0, 12.0, 15.0, 18.0, 21.0, 24.5), {}),
    # many parts, from one part up to the family's count (keys and pieces row by row, the racket's
    # four mains before its crosses, the LEGO brick's walls before its tubes)
    "keypad_keys": ("strips16_unseen5", "remote_keypad", "count", (1, 2, 3, 4, 6, 8, 10, 12), {}),
    "chocolate_pieces": ("strips16_unseen5", "chocolate_bar", "count", (1, 2, 4, 6, 8, 10, 12), {}),
    "guitar_strings": ("strips16_unseen5", "guitar_strings", "count", (1, 2, 3, 4, 5, 6), {}),
    "racket_strings": ("strips16_unseen5", "tennis_racket_strings", "count", (1, 2, 4, 5, 6, 7), {}),
    "lego_parts": ("strips16_unseen5", "lego_brick_underside", "count", (2, 4, 5, 7), {}),
}


def _set(stimuli: dict[str, Any], parameter: str, value: float) -> None:
    if parameter == "count":
        stimuli["count"] = [int(value), int(value)]
    elif parameter == "parts":  # the object cut down to its first parts (and their kinds)
        stimuli["count"] = [int(value), int(value)]
        stimuli["object"]["offsets_mm"] = stimuli["object"]["offsets_mm"][: int(value)]
        if stimuli["object"].get("part_kinds"):
            stimuli["kinds"] = stimuli["kinds"][: int(value)]
    elif parameter == "margin_mm":
        stimuli["margin_mm"] = float(value)
    elif parameter.startswith("object."):
        stimuli["object"][parameter.removeprefix("object.")] = [float(value), float(value)]
    else:
        for kind in stimuli["kinds"]:
            kind[parameter] = [float(value), float(value)]


def probe_suite(probe: str) -> dict[str, Any]:
    """A suite (as TOML data) of one family per value of the probe's ladder."""
    suite, family_name, parameter, values, fixed = PROBES[probe]
    data, _ = read_toml(suite, "suites", "suite")
    template = next(f for f in data["families"] if f["name"] == family_name)
    families = []
    for value in values:
        fam = copy.deepcopy(template)
        fam["name"] = f"{parameter}={value:g}"
        stimuli = fam["strips"]["stimuli"]
        for name, setting in fixed.items():
            _set(stimuli, name, setting)
        _set(stimuli, parameter, value)
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


def near_l_share(scene: Scene, n: int, seed: int, tol_mm: float = 1.25, arm_mm: float = 5.0) -> float:
    """Share of a training scene's frames that hold an L by chance: three contacts, one sharing its
    row with a second and its column with a third (centres within ``tol_mm``), arms over ``arm_mm``."""
    from synth.sensors.strips.stimuli import ContactGenerator

    c = ContactGenerator(scene.sensor, rasterize=False).draw_contacts(n, np.random.default_rng(seed))
    x, y, present = c["x_mm"], c["y_mm"], c["present"]
    found = np.zeros(n, dtype=bool)
    for a, b, d in itertools.permutations(range(x.shape[1]), 3):
        row = (np.abs(y[:, a] - y[:, b]) < tol_mm) & (np.abs(x[:, a] - x[:, b]) > arm_mm)
        column = (np.abs(x[:, a] - x[:, d]) < tol_mm) & (np.abs(y[:, a] - y[:, d]) > arm_mm)
        found |= present[:, a] & present[:, b] & present[:, d] & row & column
    return float(found.mean())


def ghost_twins(models: list[str], n: int, seed: int) -> dict[str, Any]:
    """Three equal studs in an L square to the strips against the diagonal pair that reads most like
    it: the L's corner stud alone with ``factor`` times its force and one stud on the free corner
    (rows and columns carry 2F and F either way; the piezo law is not linear, so the factor that
    matches best is found, from 2 to 3). Every frame of the L (``lego_2x2_square``, three studs,
    1 N each) gets its twin; how far apart their noise-free readings lie (against the noise: far
    enough apart, a model could tell them apart), and every method's r on each set."""
    from synth.sensors.strips import StripModel
    from synth.sensors.strips.stimuli import ContactGenerator, StripContacts

    data, _ = read_toml("strips16_unseen2", "suites", "suite")
    fam = copy.deepcopy(next(f for f in data["families"] if f["name"] == "lego_2x2_square"))
    for name, value in (("count", 3), ("object.rotation_deg", 0.0), ("force_n", 1.0)):
        _set(fam["strips"]["stimuli"], name, value)
    scene = parse_suite({**data, "families": [fam]}, "ghost twins").families[0].scene
    generator = ContactGenerator(scene.sensor)
    model = StripModel(scene.sensor)
    rng = np.random.default_rng(seed)
    ell = generator.draw_contacts(n, rng)
    gains = generator.draw_gains(n, rng)
    stimuli = {"L": StripContacts(ell, gains, generator.windows(ell))}
    clean_ell = model.forward(stimuli["L"])

    def twin(factor: float) -> StripContacts:
        # parts 0, 1, 2 lie at (-4, -4), (4, -4), (-4, 4): part 0 is the corner, (4, 4) the free corner
        pair = {k: v.copy() for k, v in ell.items()}
        pair["force_n"][:, 0] *= factor
        pair["y_mm"][:, 1] = ell["y_mm"][:, 2]
        pair["count"][:] = 2
        pair["present"][:, 2] = False
        pair["kind"][:, 2] = -1
        return StripContacts(pair, gains, generator.windows(pair))

    def rms_gap(stimulus: StripContacts) -> np.ndarray:
        return np.sqrt(((model.forward(stimulus) - clean_ell) ** 2).mean(axis=1))

    factors = np.round(np.arange(2.0, 3.001, 0.1), 2)
    factor = float(min(factors, key=lambda f: float(np.median(rms_gap(twin(f))))))
    stimuli["pair"] = twin(factor)
    gap = rms_gap(stimuli["pair"])
    estimators = {m: resolve_method("strips", m, scene, threads=1) for m in [*CLASSICAL, *models]}
    r: dict[str, dict[str, float]] = {}
    for name, stimulus in stimuli.items():
        inputs = model.forward(stimulus, np.random.default_rng(seed + 1)).astype(np.float32)
        truth = model.pressure_map(stimulus)
        r[name] = {m: float(np.nanmean(pearson_per_frame(e.predict(inputs), truth))) for m, e in estimators.items()}
        print(f"ghost_twins      {name:20s} " + ", ".join(f"{m} {v:.3f}" for m, v in r[name].items()))
    noise_v = scene.sensor.readout.noise_v
    print(
        f"ghost_twins      corner x{factor:g}: rms reading difference per frame median {np.median(gap) * 1e3:.1f} mV "
        f"(noise {noise_v * 1e3:g} mV rms)"
    )
    chance = near_l_share(load_scene("strips16_wide"), 200_000, seed)
    print(f"ghost_twins      strips16_wide frames holding an L by chance (within 1.25 mm): {100 * chance:.2f} %")
    return {
        "r": r,
        "factor": factor,
        "rms_gap_median_v": float(np.median(gap)),
        "noise_v": noise_v,
        "strips16_wide_near_l_share": chance,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="*", default=["strips16", "strips16_small"])
    parser.add_argument("--suite", default="strips16_unseen", help="run this suite's probes (unless --probes)")
    parser.add_argument("--probes", nargs="+", choices=list(PROBES))
    parser.add_argument("--n", type=int, default=300, help="frames per value")
    parser.add_argument("--seed", type=int, default=7777)
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    probes = args.probes or [name for name, spec in PROBES.items() if spec[0] == args.suite]
    result = {
        "command": "python scripts/strips_unseen_probe.py " + " ".join(argv if argv is not None else sys.argv[1:]),
        "seed": args.seed,
        "frames_per_value": args.n,
        "probes": {p: run_probe(p, args.models, args.n, args.seed) for p in probes},
    }
    if args.suite == "strips16_unseen2" and not args.probes:
        result["ghost_twins"] = ghost_twins(args.models, args.n, args.seed)
    if args.json:
        atomic_write_json(args.json, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
