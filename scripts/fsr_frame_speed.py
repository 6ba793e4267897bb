"""FSR single frames: the one-frame path against the vectorised path, in one run (issue 15).

For each FSR method (``triangulation``, ``triangulation_fit`` and the shipped ``fsr`` model under
onnxruntime with 1 thread), on held-out frames of the fsr6 scene (a seed no training set uses),
timed in interleaved rounds (:func:`tactile_learn.timing.interleaved_times`), medians in us:

- ``one_frame``: ``predict`` on one frame (the single-frame path: checks and the method on Python
  floats; for the network the one-press check on floats);
- ``batch_path``: the same frame through the vectorised path (the input check, then
  ``predict_batch`` for triangulation; the network, then the batch one-press check);
- ``b1024_us_per_frame``: one ``predict`` call on 1024 frames of the kind, over 1024;

each for frames without contact (the film at rest, or a press too light to reach any disc's break
force) and frames with a press, reported separately: the two cost very differently, and the
median over a mixed set is the median of whichever kind is more common.

    python scripts/fsr_frame_speed.py --json results/fsr_frame_speed.json
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

from synth.dataset import simulate_shard
from synth.scene import load_scene
from tactile_learn.bench import machine_info, record_run
from tactile_learn.fsr_check import one_press_check
from tactile_learn.methods import shipped_models
from tactile_learn.runtime import OnnxEstimator
from tactile_learn.tasks import get_task
from tactile_learn.timing import interleaved_times

SEED = 424_242  # held out: no training or validation set of the fsr scenes uses it


def _batch_path(estimator: Any) -> Callable[[np.ndarray], np.ndarray]:
    """The vectorised path of ``estimator`` for any batch (also one frame)."""
    if isinstance(estimator, OnnxEstimator):
        run, output, name = estimator.run_
        check = one_press_check(estimator.scene_).prepare()

        def network(frames: np.ndarray) -> np.ndarray:
            x = estimator.input_check_(frames)
            out = np.empty((len(x), 6), dtype=np.float32)
            out[:, :5] = run(output, {name: x})[0]
            out[:, 5] = check.p_one_press(x, out[:, :5])
            return out

        return network
    return lambda frames: estimator.predict_batch(estimator.input_check_(frames))


def _on_batch(call: Callable[[np.ndarray], Any], big: np.ndarray) -> Callable[[np.ndarray], Any]:
    """``call`` on ``big`` whatever frame the timer hands it."""
    return lambda _frame: call(big)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=400, help="held-out frames drawn (both kinds)")
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--per-round", type=int, default=20)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    load_before = os.getloadavg()[0]
    scene = load_scene("fsr6")
    task = get_task("fsr")
    data = simulate_shard(scene, SEED, 0, args.frames)
    frames = np.ascontiguousarray(task.example_inputs(data, scene), dtype=np.float32)
    methods: dict[str, Any] = {name: factory(scene) for name, factory in task.classical_methods().items()}
    methods["fsr.onnx"] = OnnxEstimator(shipped_models("fsr")["fsr"], threads=1).prepare()
    # kinds by what the first method detects (the same frames for every method)
    detected = methods["triangulation"].predict(frames)[:, 3] > 0.5
    kinds = {"no_contact": frames[~detected], "contact": frames[detected]}
    calls: dict[str, Callable[[np.ndarray], Any]] = {}
    inputs: dict[str, np.ndarray] = {}
    for name, est in methods.items():
        batch = _batch_path(est)
        for kind, sel in kinds.items():
            for way, call in (("one_frame", est.predict), ("batch_path", batch)):
                calls[f"{name}|{kind}|{way}"], inputs[f"{name}|{kind}|{way}"] = call, sel
            np.testing.assert_allclose(  # the two paths agree on these frames (to float32 rounding)
                np.concatenate([est.predict(sel[i : i + 1]) for i in range(len(sel))]), batch(sel), rtol=1e-5, atol=1e-4
            )
            big = np.ascontiguousarray(np.resize(sel, (1024, sel.shape[1])))
            calls[f"{name}|{kind}|b1024"], inputs[f"{name}|{kind}|b1024"] = _on_batch(est.predict, big), sel
    per_round = {k: 1 if k.endswith("b1024") else args.per_round for k in calls}
    times = interleaved_times(calls, inputs, rounds=args.rounds, per_round=per_round, warmup=20)
    med = {k: float(np.median(v) * 1e6) for k, v in times.items()}
    result: dict[str, Any] = {"machine": machine_info(), "frames": {k: len(v) for k, v in kinds.items()}, "methods": {}}
    for name in methods:
        row: dict[str, Any] = {}
        for kind in kinds:
            one, vec = med[f"{name}|{kind}|one_frame"], med[f"{name}|{kind}|batch_path"]
            per_frame = med[f"{name}|{kind}|b1024"] / 1024
            row[kind] = {
                "one_frame_us": one,
                "batch_path_us": vec,
                "b1024_us_per_frame": per_frame,
                "speedup": vec / one,
                "ratio_to_b1024": one / per_frame,
            }
            print(
                f"{name:18s} {kind:10s} one-frame {one:8.1f} us  batch path {vec:8.1f} us  "
                f"({vec / one:5.1f}x)  b1024 {per_frame:6.2f} us/frame  ratio {one / per_frame:5.1f}",
                flush=True,
            )
        result["methods"][name] = row
    record_run(result, "fsr_frame_speed.py", argv, load_before, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
