"""Average the weights of several epochs of one run (a uniform "soup" of its last epochs): the
material is what ``tactile-learn train --keep-epochs`` writes, ``RUN/epoch-NNN.pt``.

    python scripts/strips_soup.py runs/strips16_gpu1 --last 3 --out runs/strips16_gpu1_last3

The epochs of one run share the network, its size and its normalisation; an average of the last
few epochs of a run whose learning rate has annealed sits nearer the middle of the basin than any
one of them. The result is a run folder (``model.pt``) that ``train --init`` and ``export`` read.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from synth.errors import ConfigError, ModelError
from tactile_learn.checkpoints import MODEL, load_weights, save_torch


def epoch_files(run: Path) -> list[Path]:
    """The run's epoch weights in epoch order (``train --keep-epochs``)."""
    files = sorted(run.glob("epoch-*.pt"))
    if not files:
        raise ModelError(f"{run}: no epoch weights (train the run with --keep-epochs)")
    return files


def average(files: list[Path]) -> dict:
    """The first file's contents with the uniform average of every file's weights."""
    saved = [load_weights(f) for f in files]
    first = saved[0]
    for f, s in zip(files[1:], saved[1:], strict=True):
        if (s["task"], s["size"], s["stats"]) != (first["task"], first["size"], first["stats"]):
            raise ModelError(f"{f} and {files[0]} differ in task, size or normalisation: nothing to average")
        if s["state_dict"].keys() != first["state_dict"].keys():
            raise ModelError(f"{f} and {files[0]} hold different networks")
    state = {
        k: sum(s["state_dict"][k] for s in saved) / len(saved) if v.is_floating_point() else v
        for k, v in saved[-1]["state_dict"].items()
    }
    # the run's own record (model.pt: data, schedule, device), which export copies into the card
    finished = files[-1].parent / MODEL
    record = load_weights(finished)["result"] if finished.is_file() else dict(saved[-1].get("result") or {})
    result = {**record, "averaged": {"epochs": [str(f) for f in files]}}
    return {**saved[-1], "state_dict": state, "result": result}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", help="a run folder trained with --keep-epochs")
    parser.add_argument("--last", type=int, required=True, help="average this many of its last epochs")
    parser.add_argument("--out", required=True, help="run folder to write (model.pt)")
    args = parser.parse_args(argv)
    files = epoch_files(Path(args.run))
    if not 1 <= args.last <= len(files):
        raise ConfigError(f"--last: {args.last} is out of range [1, {len(files)}] (epochs of {args.run})")
    soup = average(files[-args.last :])
    soup.pop("source", None)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    save_torch(out / MODEL, soup)
    print(f"{out / MODEL}: mean of {', '.join(f.name for f in files[-args.last :])} of {args.run}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
