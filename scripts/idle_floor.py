"""Add the idle floor (``tactile_learn.idle``) to the cards of existing models.

The noise floor of the sensor at rest, measured on frames of each model's own scene with every
contact removed; ``tactile-learn export`` writes it for new models. The ONNX file is not touched
(the card's checksum is of the ONNX file), only the card's ``idle`` entry is (re)written.

    python scripts/idle_floor.py models/strips16.onnx models/fsr.onnx models/capacitive8.onnx
"""

from __future__ import annotations

import argparse
import sys

from synth.io import atomic_write_json
from tactile_learn.idle import IDLE_SEED, measure_idle_floor
from tactile_learn.runtime import OnnxEstimator, card_path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("models", nargs="+", help=".onnx models (their .json cards are updated)")
    parser.add_argument("--frames", type=int, default=20000, help="idle frames simulated per model")
    parser.add_argument("--seed", type=int, default=IDLE_SEED)
    args = parser.parse_args(argv)
    for path in args.models:
        model = OnnxEstimator(path).prepare()
        card = dict(model.card_)  # checked: the card belongs to this ONNX file
        card["idle"] = measure_idle_floor(model.card_scene_, args.frames, args.seed)
        atomic_write_json(card_path(path), card)
        print(f"{card_path(path)}: idle threshold {card['idle']['threshold']:.2f} sd over {args.frames} idle frames")
    return 0


if __name__ == "__main__":
    sys.exit(main())
