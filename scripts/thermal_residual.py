"""The calibration residual on real touches, per channel and per condition, for several model variants.

    python scripts/thermal_residual.py --label R_1 --json results/thermal_robot_residual.json

For the labelled session: ``calibrate`` once per variant (per-touch nuisance terms: none; the
object's flux; the object's flux and the heater's steps; the contact's precursor; the approach
through the closing air gap; contact events, steps of the contact conductance at the residual's
kinks; and the joint refinement in noise units, ``weighted``), and the
residual in mK and in noise sigma (both noise definitions: see
``tactile_learn.calibration.thermal_report.residual_summary``), with one contact for every
touch and with each touch's own contact, overall, per channel and per condition of
``touches.csv`` (M metal, W wood, CW cooled wood), and the calibration's wall time. The
residual's kinks (slope changes at a few instants; see ``tactile_learn.calibration.thermal_kinks``)
and its RMS per time window after the onset are printed per channel. The data: ``--data``, else
``$TACTILE_THERMAL_ROBOT``, else ``../shared/data/thermal-robot``.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from synth.io import atomic_write_json
from tactile_learn.thermal_adapt import CHANNEL_CHOICES, calibrate_recordings
from tactile_learn.thermal_recordings import read_recordings, select_recordings

sys.path.insert(0, str(Path(__file__).resolve().parent))
from thermal_robot_protocol import robot_data  # a sibling script

#: variant -> (per-touch nuisance terms, noise-weighted joint refinement)
VARIANTS: dict[str, tuple[tuple[str, ...], bool]] = {
    "none": ((), False),
    "object_flux": (("object_flux",), False),
    "object_flux+heater_steps": (("object_flux", "heater_steps"), False),
    "contact_precursor": (("contact_precursor",), False),
    "weighted": ((), True),
    "contact_precursor+weighted": (("contact_precursor",), True),
    "approach": (("approach",), False),
    "approach+weighted": (("approach",), True),
    "contact_events": (("contact_events",), False),
    "contact_events+weighted": (("contact_events",), True),
    "drift_ends": (("drift_ends",), False),
}


def by_condition(report: dict[str, Any], conditions: dict[str, str]) -> dict[str, Any]:
    """RMS (mK) per condition and channel: the root mean square of the touches' RMS (the records
    are of equal length within a few samples)."""
    out: dict[str, Any] = {}
    for cond in sorted(set(conditions.values())):
        rows = [t for t in report["touches"] if conditions[Path(t["file"]).name] == cond]
        entry = {}
        for ch in report["channels_fitted"]:
            for key, name in ((f"{ch}_rms_k", "shared_contact"), (f"{ch}_own_rms_k", "own_contact")):
                entry[f"{ch}_{name}_mk"] = 1e3 * math.sqrt(sum(r[key] ** 2 for r in rows) / len(rows))
        out[cond] = entry
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=None)
    parser.add_argument("--label", default="R_1")
    parser.add_argument("--variants", default="none,weighted", help=f"comma list of {', '.join(VARIANTS)}")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    data = robot_data(args.data)
    out: dict[str, Any] = {"command": " ".join(["python", "scripts/thermal_residual.py", *(argv or sys.argv[1:])])}
    with tempfile.TemporaryDirectory() as tmp:
        labelled = select_recordings(data, Path(tmp) / "labelled", "session", [args.label])
        conditions = {Path(t.file).name: str(t.info.get("condition", "?")) for t in read_recordings(labelled)}
        for variant in args.variants.split(","):
            started = time.perf_counter()
            nuisance, weighted = VARIANTS[variant]
            _, report = calibrate_recordings(
                labelled, CHANNEL_CHOICES["all"], nuisance=nuisance, noise_weighted=weighted
            )
            seconds = time.perf_counter() - started
            out[variant] = {
                "calibration_s": seconds,
                "residual": report["residual"],
                "by_condition": by_condition(report, conditions),
                "noise": report["noise"],
                "at_bound": report["at_bound"],
                "not_identified": report["not_identified"],
                "parameters": {k: v["value"] for k, v in report["parameters"].items()},
                "touches": report["touches"],
                "contact_events": report.get("contact_events"),
            }
            res = report["residual"]
            print(
                f"{variant}: {seconds:.0f} s; own contact heated {res['heated']['rms_k'] * 1e3:.2f} mK "
                f"({res['heated']['rms_sigma']:.1f} / {res['heated']['rms_sigma_precontact']:.1f} sigma), passive "
                f"{res['passive']['rms_k'] * 1e3:.2f} mK ({res['passive']['rms_sigma']:.1f} / "
                f"{res['passive']['rms_sigma_precontact']:.1f} sigma); shared contact heated "
                f"{res['shared_contact']['heated']['rms_k'] * 1e3:.2f}, passive "
                f"{res['shared_contact']['passive']['rms_k'] * 1e3:.2f} mK",
                flush=True,
            )
            for ch in report["channels_fitted"]:
                windows = ", ".join(
                    f"[{'-' if w['from_s'] is None else w['from_s']}, {'-' if w['to_s'] is None else w['to_s']}) "
                    f"{w['rms_k'] * 1e3:.1f} mK {100 * w['share_of_squares']:.0f} %"
                    for w in res["windows"][ch]
                )
                print(f"  {ch} by time after the onset: {windows}", flush=True)
            if report.get("contact_events"):
                ev = report["contact_events"]
                print(f"  contact events: {ev['count']}, factors at a bound: {ev['factors_at_bound']}", flush=True)
            for ch in report["channels_fitted"]:
                k = res["kinks"][ch]
                print(
                    f"  {ch} kinks: {k['kinks']}; RMS {k['rms_k'] * 1e3:.2f} mK, away from them "
                    f"{k['rms_away_from_kinks_k'] * 1e3:.2f}; after {res['kinks']['after_onset_s']} s about a line "
                    f"{k['late_rms_about_a_line_k'] * 1e3:.2f}, with a hinge at each kink "
                    f"{k['late_rms_about_a_line_and_hinges_k'] * 1e3:.2f} mK",
                    flush=True,
                )
    if args.json:
        atomic_write_json(args.json, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
