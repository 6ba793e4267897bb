"""Do specialists' priors transfer? The margin matrix of one-family specialists across a suite's families.

A specialist (docs/strips.md, "What a specialist reaches on the losing families") is a strip network
fine-tuned on one family of a suite alone; its card's scene is ``SUITE/FAMILY``. Scored on every family
of that suite by ``scripts/strips_unseen.py`` (one run, the same frames for every model), its margin over
the best classical rule on its own family says what the readings hold when the family is known, and its
margins on the other families say how much of that is the family's own prior::

    python scripts/strips_unseen.py strips16 runs/s12spec-*/specialist.onnx --suite strips16_unseen12 \\
        --seeds 5151 6262 --n 600 --json results/strips_specialists12/unseen12.json
    python scripts/strips_transfer.py results/strips_specialists12/unseen12.json \\
        --json results/strips_specialists12/transfer.json

Rows: the family a specialist was trained on; columns: the family it is judged on. Models whose card
names no family of the suite (e.g. the shipped default, or a network trained on several families) are
listed beside the matrix with their margins on every family.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import strips_unseen


def card_family(model: str, suite: str) -> str | None:
    """The family a model was trained on alone, from its card: one training dataset whose scene is
    ``SUITE/FAMILY``. None for any other model (a shipped name, or a network trained on several
    datasets, whose card names the first one's scene)."""
    path = Path(model).with_suffix(".json")
    if not path.is_file():
        return None
    card = json.loads(path.read_text())
    data_path = card.get("training", {}).get("data", {}).get("path")
    if not isinstance(data_path, str):
        return None
    scene = card.get("scene", {}).get("name", "")
    prefix = f"{suite}/"
    return scene[len(prefix) :] if isinstance(scene, str) and scene.startswith(prefix) else None


def transfer(result: dict[str, Any], families_of: dict[str, str | None]) -> dict[str, Any]:
    """The margin matrix (specialist's family x judged family), its diagonal and off-diagonal means."""
    families = list(result["families"])
    specialists = {fam: model for model, fam in families_of.items() if fam is not None}
    unknown = sorted(set(specialists) - set(families))
    if unknown:
        raise SystemExit(f"specialists of families the result does not hold: {', '.join(unknown)}")
    rows = [fam for fam in families if fam in specialists]
    if not rows:
        raise SystemExit(f"no model in the result is a specialist of a {result['suite']} family (card scene)")
    matrix = np.array(
        [[result["families"][col]["models"][specialists[row]]["margin"] for col in families] for row in rows]
    )
    judged = [families.index(row) for row in rows]
    own = matrix[np.arange(len(rows)), judged]
    off = np.ones_like(matrix, dtype=bool)
    off[np.arange(len(rows)), judged] = False
    others = {
        model: [result["families"][col]["models"][model]["margin"] for col in families]
        for model, fam in families_of.items()
        if fam is None
    }
    best_other = {
        col: max(
            ((row, float(matrix[i, j])) for i, row in enumerate(rows) if row != col),
            key=lambda item: item[1],
            default=(None, float("nan")),
        )
        for j, col in enumerate(families)
    }
    return {
        "suite": result["suite"],
        "seeds": result["seeds"],
        "frames_per_family": result["frames_per_family"],
        "families": families,
        "specialists": rows,
        "models": {row: specialists[row] for row in rows},
        "margin": matrix.tolist(),
        "own_family": dict(zip(rows, own.tolist(), strict=True)),
        "own_family_mean": float(own.mean()),
        "own_family_below": [row for row, m in zip(rows, own, strict=True) if m < 0],
        "other_families_mean": float(matrix[off].mean()) if off.any() else float("nan"),
        "other_families_above_floor": float(np.mean(matrix[off] >= 0.05)) if off.any() else float("nan"),
        "best_other_specialist": {col: {"family": fam, "margin": m} for col, (fam, m) in best_other.items()},
        "other_models": others,
    }


def markdown(summary: dict[str, Any], command: str) -> str:
    families = summary["families"]
    short = [f"{i + 1}" for i in range(len(families))]
    lines = [
        f"# Specialists across `{summary['suite']}`: margin over the best classical rule, "
        f"{summary['frames_per_family']} frames a family at seeds " + ", ".join(str(s) for s in summary["seeds"]),
        "",
        f"`{command}`",
        "",
        "Rows: the family a specialist was trained on; columns: the family judged (numbered as in the rows' "
        "order below); the diagonal in bold.",
        "",
        "| trained on \\ judged | " + " | ".join(short) + " |",
        "|---|" + "---:|" * len(families),
    ]
    for i, row in enumerate(summary["specialists"]):
        cells = []
        for j, col in enumerate(families):
            value = f"{summary['margin'][i][j]:+.3f}"
            cells.append(f"**{value}**" if col == row else value)
        lines.append(f"| {families.index(row) + 1} {row} | " + " | ".join(cells) + " |")
    for model, margins in summary["other_models"].items():
        lines.append(f"| `{model}` | " + " | ".join(f"{m:+.3f}" for m in margins) + " |")
    lines += [
        "",
        f"- own family (the diagonal): mean **{summary['own_family_mean']:+.4f}**, below the rule: "
        + (", ".join(summary["own_family_below"]) or "none"),
        f"- other families (off the diagonal): mean **{summary['other_families_mean']:+.4f}**; "
        f"share at or above +0.05: {100 * summary['other_families_above_floor']:.1f} %",
        "- best specialist of another family, per judged family: "
        + "; ".join(
            f"{col} {entry['margin']:+.3f} ({entry['family']})"
            for col, entry in summary["best_other_specialist"].items()
            if entry["family"] is not None
        ),
    ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("result", help="JSON written by scripts/strips_unseen.py (specialists among its models)")
    parser.add_argument("--json", help="write the matrix here, and the Markdown table beside it (.md)")
    args = parser.parse_args(argv)
    result = json.loads(Path(args.result).read_text())
    if "families" not in result or "summary" not in result:
        raise SystemExit(f"{args.result}: not a result of scripts/strips_unseen.py")
    models = list(result["summary"])
    summary = transfer(result, {m: card_family(m, result["suite"]) for m in models})
    command = "python scripts/strips_transfer.py " + " ".join(argv if argv is not None else sys.argv[1:])
    summary["command"] = command
    table = markdown(summary, command)
    strips_unseen.report(summary, table, args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
