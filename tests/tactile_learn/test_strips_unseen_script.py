"""scripts/strips_unseen.py and strips_unseen_probe.py on a few frames: the margins, loss and flag
shares are what their definitions say, recomputed here from the same frames."""

from __future__ import annotations

import sys

import numpy as np

from synth.scene import read_toml
from synth.suite import parse_suite
from tactile_learn.methods import resolve_method
from tactile_learn.metrics import pearson_per_frame
from tactile_learn.strips_guard import CheckedStripModel
from tactile_learn.suites import suite_eval_data
from tests.paths import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "scripts"))
import strips_unseen
import strips_unseen_probe

MODEL = str(REPO_ROOT / "models" / "strips16_small.onnx")


def _two_families():  # type: ignore[no-untyped-def]
    data, _ = read_toml("strips16_unseen", "suites", "suite")
    picked = [f for f in data["families"] if f["name"] in ("bottle_cap", "five_fingertips")]
    return parse_suite({**data, "families": picked}, "two families")


def test_margins_losses_and_flags_follow_their_definitions() -> None:
    suite = _two_families()
    in_family = suite_eval_data(suite, 20, 99)["bottle_cap"]  # stands for the training distribution
    result = strips_unseen.evaluate(suite, [MODEL], n=12, seeds=[3, 4], test=in_family, log=lambda _: None)
    seed3 = result["per_seed"]["3"]
    frames = suite_eval_data(suite, 12, 3)
    guard = CheckedStripModel(MODEL).prepare()
    in_family_residual = guard.check(in_family.inputs)["residual"]
    for name, data in frames.items():
        truth = data.truth["pressure"]
        r = {
            m: pearson_per_frame(resolve_method("strips", m, suite.base).predict(data.inputs), truth)
            for m in ("intersection", "projection", MODEL)
        }
        row = seed3[name]
        for m, values in r.items():
            assert np.isclose(row["methods"][m]["r"], np.nanmean(values))
        best = max(np.nanmean(r["intersection"]), np.nanmean(r["projection"]))
        model = row["models"][MODEL]
        assert np.isclose(model["margin"], np.nanmean(r[MODEL]) - best)
        losing = r[MODEL] < np.fmax(r["intersection"], r["projection"]) - strips_unseen.LOSS_MARGIN
        assert np.isclose(model["losing_share"], losing.mean())
        assert np.isclose(model["flagged_share"], guard.check(data.inputs)["flagged"].mean())
    fam = result["families"]["bottle_cap"]
    per_seed = [result["per_seed"][s]["bottle_cap"]["models"][MODEL]["margin"] for s in ("3", "4")]
    assert fam["margin_per_seed"][MODEL] == per_seed
    assert np.isclose(fam["models"][MODEL]["margin"], np.mean(per_seed))
    checked_costs = 0
    for name, fam in result["families"].items():
        model = fam["models"][MODEL]
        medians = [result["per_seed"][s][name]["models"][MODEL]["losing_residual_median"] for s in ("3", "4")]
        if np.isfinite(model["losing_residual_median"]):
            limit = np.nanmean(medians)
            assert np.isclose(model["test_flagged_at_losing_median"], np.mean(in_family_residual >= limit))
            checked_costs += 1
    assert checked_costs  # five fingertips: the small model loses some of them
    table = strips_unseen.markdown({**result, "command": "x"}, [MODEL])
    assert table.count("| bottle_cap |") == 2 and "| five_fingertips |" in table


def test_probe_ladders_set_one_parameter_and_keep_the_rest() -> None:
    data = strips_unseen_probe.probe_suite("punch_radius")
    suite = parse_suite(data, "probe")
    _, family, parameter, values, _ = strips_unseen_probe.PROBES["punch_radius"]
    assert len(suite.families) == len(values)
    original = _two_families().family(family).scene.sensor.stimuli
    for fam, value in zip(suite.families, values, strict=True):
        (kind,) = fam.scene.sensor.stimuli.kinds
        assert getattr(kind, parameter) == (value, value)
        assert kind.force_n == original.kinds[0].force_n
    counts = parse_suite(strips_unseen_probe.probe_suite("fingertip_count"), "probe").families
    assert [f.scene.sensor.stimuli.count for f in counts] == [(v, v) for v in (2, 3, 4, 5)]


def test_a_probe_can_cut_an_object_down_to_its_first_parts() -> None:
    """The watch's case alone: one part, the case's kind only, and the other settings as fixed."""
    suite = parse_suite(strips_unseen_probe.probe_suite("watch_case_radius"), "probe")
    values = strips_unseen_probe.PROBES["watch_case_radius"][3]
    for fam, value in zip(suite.families, values, strict=True):
        stimuli = fam.scene.sensor.stimuli
        assert stimuli.count == (1, 1) and stimuli.margin_mm == 12.0
        assert stimuli.object is not None and stimuli.object.offsets_mm == ((0.0, 0.0),)
        (case,) = stimuli.kinds
        assert case.kind == "punch" and case.radius_mm == (value, value)


def test_every_probe_ladder_parses_into_one_family_per_value() -> None:
    for probe, (_, _, parameter, values, _) in strips_unseen_probe.PROBES.items():
        suite = parse_suite(strips_unseen_probe.probe_suite(probe), f"probe {probe}")
        assert [f.name for f in suite.families] == [f"{parameter}={v:g}" for v in values], probe
