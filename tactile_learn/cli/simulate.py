"""tactile-learn simulate: what would the sensor read for my own stimulus?"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

import numpy as np

from synth.dataset import load_arrays
from synth.errors import ConfigError
from synth.io import atomic_save_npz
from synth.scene import Scene, load_scene
from synth.sensors import sensor_model
from synth.sensors.capacitive import Presses
from synth.sensors.fsr import FsrPresses
from synth.sensors.model import SensorModel, stored_readings
from synth.sensors.strips import PressureField, StripModel
from synth.sensors.thermal import ThermalModel, Touches
from tactile_learn.cli.common import non_negative_int, on_off

#: task -> (stimulus fields, the array that says whether a single stimulus was given and its ndim
#: without the batch axis, the stimulus from arrays)
_Build = Callable[[dict[str, np.ndarray], Any], Any]
STIMULI: dict[str, tuple[dict[str, str], tuple[str, ...], int, _Build]] = {
    "strips": (PressureField.FIELDS, ("field_kpa", "pressure"), 2, lambda a, c: PressureField.from_arrays(a, c)),
    "capacitive": (Presses.FIELDS, ("field_kpa", "pressure"), 3, lambda a, c: Presses.from_arrays(a, c)),
    "fsr": (FsrPresses.FIELDS, ("xy_mm",), 1, lambda a, c: FsrPresses.from_arrays(a)),
    "thermal": (Touches.FIELDS, ("object_c",), 0, lambda a, c: Touches.from_arrays(a, c)),
}


def _fields_help() -> str:
    lines = []
    for task, (fields, _, _, _) in STIMULI.items():
        lines.append(f"{task} stimulus arrays:")
        lines.extend(f"  {name:18s} {what}" for name, what in fields.items())
    return "\n".join(lines)


HELP = "run a sensor's forward model (physics -> transducer -> noise -> ADC) on a user's stimulus"
EXAMPLES = f"""\
  tactile-learn simulate --scene strips16 --stimulus my_field.npz --out my_readings.npz
  tactile-learn simulate --scene strips5 --stimulus f.npz --out r.npz --noise on --seed 3
  tactile-learn simulate --scene fsr6 --stimulus presses.npz --out codes.npz --noise on
  tactile-learn simulate --scene thermal --stimulus touch.npz --out curves.npz
  tactile-learn simulate --scene capacitive8 --stimulus press.npz --out cells.npz
The stimulus .npz holds the arrays of the scene's sensor's stimulus (B stimuli, batch first; a
single stimulus may leave the batch axis out). Without --noise the readings are the clean signal
(the FSR's: clean ADC codes); with it, noise and the ADC. E.g. in Python:
  np.savez("presses.npz", xy_mm=[[0, 0], [10, 5.8]], force_n=[2.0, 6.0], tip_radius_mm=4.0)
  np.savez("touch.npz", object_c=[20.0, 20.0], material=["aluminium", "oak"], contact_s=2.0)
  np.savez("my_field.npz", field_kpa=field)  # strips16: (64, 64) cells of 0.625 mm, kPa
  np.savez("press.npz", field_kpa=frames)  # capacitive8: (F, 42, 42) cells of 0.45 mm, 5 of them padding
Strip fields: cell (k, l) is centred at y = (k+0.5) h, x = (l+0.5) h with h = pitch / s (s =
samples_per_pitch); capacitive fields lie on the padded lattice (geometry.lattice_shape).
{_fields_help()}
The output holds 'readings' and 'readings_clean' (noise-free) and, per sensor: strips 'pressure'
(the N x M intersection map, kPa), fsr 'sensor_force_n' (load on each disc, N), capacitive
'cell_load' (load on every tab, N), thermal 'time_s' (the record's sample times)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scene", required=True, help="scene name or .toml path (strips, fsr, thermal, capacitive)")
    parser.add_argument(
        "--stimulus", "--pressure", dest="stimulus", required=True, help=".npz with the stimulus arrays (see below)"
    )
    parser.add_argument("--out", required=True, help="output .npz")
    parser.add_argument("--noise", type=on_off, default=False, help="on|off: noise and ADC (default off)")
    parser.add_argument(
        "--seed",
        type=non_negative_int,
        default=0,
        help="noise seed (with --noise on; default 0: the same noise every run)",
    )


def simulate_arrays(
    scene: Scene, arrays: dict[str, np.ndarray], noise: bool = False, seed: int = 0
) -> dict[str, np.ndarray]:
    """The sensor's outputs for the stimulus ``arrays`` (batch first, or one stimulus without the
    batch axis: the outputs then have none either)."""
    if scene.task not in STIMULI:
        kinds = ", ".join(STIMULI)
        raise ConfigError(f"--scene: simulate takes a {kinds} scene; {scene.name!r} is a {scene.task!r} scene")
    _, mains, single_ndim, build = STIMULI[scene.task]
    main = next((np.asarray(arrays[m]) for m in mains if m in arrays), None)
    single = main is not None and main.ndim == single_ndim
    if single:
        arrays = {k: np.asarray(v)[None] for k, v in arrays.items()}
    # a user's strip field lies on the array's own lattice: no padding for contacts past the border
    # (the operators of StripSensor(config), as before the sensor models)
    model: SensorModel[Any] = StripModel(scene.sensor, pad=0) if scene.task == "strips" else sensor_model(scene)
    stimulus = build(arrays, scene.sensor)
    dtype = model.reading_spec().dtype
    out = {
        "readings": stored_readings(model, stimulus, np.random.default_rng(seed) if noise else None).astype(dtype),
        "readings_clean": model.forward(stimulus).astype(dtype),
    }
    if isinstance(model, StripModel):
        out["pressure"] = model.pressure_map(stimulus)
    elif scene.task == "fsr":
        out["sensor_force_n"] = model.physics(stimulus).astype(np.float32)
    elif scene.task == "capacitive":
        out["cell_load"] = model.physics(stimulus).astype(np.float32)
    if single:
        out = {k: v[0] for k, v in out.items()}
    if isinstance(model, ThermalModel):
        out["time_s"] = model.time_s.astype(np.float32)
    return out


def run(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene)
    out = simulate_arrays(scene, load_arrays(args.stimulus), args.noise, args.seed)
    atomic_save_npz(args.out, out)
    shapes = ", ".join(f"{k} {v.shape}" for k, v in out.items())
    print(f"wrote {args.out}: {shapes}")
    return 0
