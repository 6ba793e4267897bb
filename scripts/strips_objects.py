"""Every everyday object seen so far as training data: a generic strip expert fine-tuned on all the families of
the unseen-shape rounds up to K, routed beside ``strips16`` (issue 12; docs/strips.md, "Round 9").

Rounds 1-8 (97 families) were each written to be unlike everything before them, and each was judged blind
once; after that they are simply 97 objects the repository can draw. Stops 29-31 trained on parts of them
(rounds 1-4 in three clustered experts) or on objects drawn from no name (random shapes, product fields,
arrangements); none has trained one network on all of them. This script writes the frames, trains the
router that sends a frame to the objects' expert or to ``strips16``, and prints the training commands::

    python scripts/strips_objects.py data --rounds 8 --out data/objects          # 1,500 frames a family
    python scripts/strips_objects.py plan --rounds 7 --data data/objects --out runs/objects7
    python scripts/strips_objects.py plan --rounds 8 --teacher --data data/objects --out runs/objects8d
    python scripts/strips_objects.py router --rounds 7 --data data/objects --out runs/objects-router7
    python scripts/strips_objects.py router --two-spheres --threshold 0.3 --rounds 10 --data data/objects \
        --out runs/sphere-router-t0.3 --expert runs/objects10c/candidate.onnx   # round 12's (docs/strips.md)

``--rounds K`` means rounds 1..K. Family ``i`` (in the suite's order) of round ``k`` is drawn at seed
``SEED + 100 * k + i``; no evaluation in the repository uses seeds in that range (evaluations draw at
5151 / 6262, specialists at 93xx / 94xx).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
import strips_prior_router
from strips_family_data import write_family

from synth.suite import load_suite

SEED = 12000
FRAMES_PER_FAMILY = 1500
ROUTER_FRAMES_PER_FAMILY = 300
#: ``arr``'s training mixture (docs/strips.md, "Round 8"): the shape library, two spheres, product fields,
#: random shapes and arrangements; the objects are added to it. Arrangements first: ``train`` checks the
#: validation set's scene against the first folder's
BASE_DATA = ("data/arrangements-train", "data/pf-wide-train", "data/pf-spheres-train", "data/products-train",
             "data/shapes-train")  # fmt: skip
INIT = "runs/arr/model.pt"
VAL = "data/arrangements-val"
EPOCHS, LR = 6, 2e-4
#: round 10's experts: the default teaches the frames of its own prior (the shape library, two spheres)
TEACHER = "models/strips16.pt"
TAUGHT = ("data/pf-wide-train", "data/pf-spheres-train")
#: the re-trained router's generic side: the stop-30 router's generic frames, arrangements and the objects
ROUTER_GENERIC_EXTRA = {"data/arrangements-train": 10000}
#: round 12's router: two spheres alone on the library side (the one set the library network is kept for),
#: against as many frames of everything else - the shape library, the mixed scene, random shapes, product
#: fields, arrangements - and :data:`SPHERE_ROUTER_FRAMES_PER_FAMILY` of each object family
SPHERE_ROUTER_LIBRARY = {"data/pf-spheres-train": 20000}
SPHERE_ROUTER_GENERIC = {"data/pf-wide-train": 5000, "data/shapes-mixed-train": 3000, "data/shapes-train": 3000,
                         "data/products-train": 3000, "data/arrangements-train": 3000}  # fmt: skip
SPHERE_ROUTER_FRAMES_PER_FAMILY = 25


def round_suite(k: int) -> str:
    """The shipped suite of round ``k`` (round 1 is ``strips16_unseen``)."""
    if not 1 <= k <= 99:
        raise ValueError(f"round must be 1..99, got {k}")
    return "strips16_unseen" if k == 1 else f"strips16_unseen{k}"


def object_folders(rounds: int, root: Path) -> list[tuple[int, int, str, Path]]:
    """(round, index, family, folder) of every family of rounds 1..``rounds``, in a fixed order."""
    out = []
    for k in range(1, rounds + 1):
        suite = round_suite(k)
        for i, family in enumerate(load_suite(suite).families):
            out.append((k, i, family.name, root / f"{suite}-{family.name}"))
    return out


def write_data(rounds: int, root: Path, n: int = FRAMES_PER_FAMILY, log: Any = print) -> None:
    """``n`` frames of every family of rounds 1..``rounds``; a folder whose manifest exists is kept (resume)."""
    start = time.perf_counter()
    for k, i, family, folder in object_folders(rounds, root):
        if not (folder / "manifest.json").exists():
            write_family(round_suite(k), family, n, SEED + 100 * k + i, folder)
    log(f"{rounds} rounds of objects in {time.perf_counter() - start:.0f} s -> {root}")


def plan(rounds: int, root: Path, out: Path, teacher: bool = False) -> str:
    """The training command of the objects' expert on rounds 1..``rounds`` (one thread); ``teacher``:
    ``strips16``'s maps are the targets of the shape library's and the two spheres' frames
    (:data:`TAUGHT`), the truth of the rest (docs/strips.md, "Round 10")."""
    folders = [str(f) for *_, f in object_folders(rounds, root)]
    command = (
        f"tactile-learn train --task strips --data {' '.join([*BASE_DATA, *folders])} --val {VAL} --out {out} "
        f"--init {INIT} --epochs {EPOCHS} --lr {LR} --threads 1 --val-limit 4000"
    )
    return command + (f" --teacher {TEACHER} --teacher-data {' '.join(TAUGHT)}" if teacher else "")


def train_router(rounds: int, root: Path, out: Path, expert: str) -> dict[str, Any]:
    """The stop-30 router's recipe with the objects of rounds 1..``rounds`` (their first
    :data:`ROUTER_FRAMES_PER_FAMILY` frames) and arrangements added to the generic side: a frame of an
    object goes to ``expert``, a frame of the shape library or two spheres to ``strips16``."""
    generic = dict(strips_prior_router.GENERIC) | ROUTER_GENERIC_EXTRA
    generic |= {str(f): ROUTER_FRAMES_PER_FAMILY for *_, f in object_folders(rounds, root)}
    models = {"library": strips_prior_router.MODELS["library"], "generic": expert}
    return strips_prior_router.train(out, generic=generic, models=models)


def train_sphere_router(
    rounds: int, root: Path, out: Path, expert: str, threshold: float = strips_prior_router.THRESHOLD
) -> dict[str, Any]:
    """Round 12's router: two-sphere frames go to ``strips16``, every other frame - the shape library's
    included - to ``expert`` (:data:`SPHERE_ROUTER_LIBRARY`, :data:`SPHERE_ROUTER_GENERIC` and the
    objects of rounds 1..``rounds``), a frame whose probability of generic is at least ``threshold``."""
    generic = dict(SPHERE_ROUTER_GENERIC)
    generic |= {str(f): SPHERE_ROUTER_FRAMES_PER_FAMILY for *_, f in object_folders(rounds, root)}
    models = {"library": strips_prior_router.MODELS["library"], "generic": expert}
    return strips_prior_router.train(
        out, generic=generic, models=models, library=SPHERE_ROUTER_LIBRARY, threshold=threshold
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    for name in ("data", "plan", "router"):
        p = sub.add_parser(name)
        p.add_argument("--rounds", type=int, required=True, help="use rounds 1..K")
        p.add_argument("--out", type=Path, required=True)
        if name != "data":
            p.add_argument("--data", type=Path, default=Path("data/objects"))
        if name == "plan":
            p.add_argument("--teacher", action="store_true", help=f"{TEACHER} teaches {', '.join(TAUGHT)}")
        if name == "router":
            p.add_argument("--expert", required=True, help="the objects' expert's ONNX file")
            p.add_argument("--two-spheres", action="store_true", help="two spheres alone on the library side")
            p.add_argument(
                "--threshold",
                type=float,
                default=strips_prior_router.THRESHOLD,
                help="--two-spheres: the probability of generic that sends a frame to the expert",
            )
    args = parser.parse_args(argv)
    if args.command == "data":
        write_data(args.rounds, args.out)
    elif args.command == "plan":
        print(plan(args.rounds, args.data, args.out, args.teacher))
    else:
        if args.two_spheres:
            card = train_sphere_router(args.rounds, args.data, args.out, args.expert, args.threshold)
        else:
            card = train_router(args.rounds, args.data, args.out, args.expert)
        print(json.dumps({k: card[k] for k in ("held_out_accuracy", "threshold")}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
