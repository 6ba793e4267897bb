"""tactile-learn simulate: what would the sensor read for my own pressure field?"""

from __future__ import annotations

import argparse

import numpy as np

from synth.dataset import load_arrays
from synth.errors import ConfigError, InputError
from synth.io import atomic_save_npz
from synth.scene import load_scene
from synth.sensors.strips import StripSensor
from tactile_learn.cli.common import non_negative_int, on_off

HELP = "run the strip array's forward model on a user's pressure field"
EXAMPLES = """\
  tactile-learn simulate --scene strips16 --pressure my_field.npz --out my_readings.npz
  tactile-learn simulate --scene strips5 --pressure f.npz --out r.npz --noise on --seed 3
The input .npz holds 'pressure': the surface pressure in kPa on the scene's fine lattice, shape
(B, N*s, M*s) or (N*s, M*s), cell (k, l) centred at y = (k+0.5) h, x = (l+0.5) h with h = pitch / s
(s = samples_per_pitch; 64 x 64 cells of 0.625 mm for strips16); optionally 'gains' (B, N+M).
The output holds 'readings' (B, N+M) in V, 'pressure' (the N x M intersection map, kPa) and
'readings_clean' (noise-free)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scene", required=True, help="strip scene name or .toml path")
    parser.add_argument("--pressure", required=True, help=".npz with the field 'pressure' (kPa)")
    parser.add_argument("--out", required=True, help="output .npz")
    parser.add_argument("--noise", type=on_off, default=False, help="on|off: electrical noise and ADC (default off)")
    parser.add_argument("--seed", type=non_negative_int, default=0, help="noise seed (with --noise on)")


def run(args: argparse.Namespace) -> int:
    scene = load_scene(args.scene)
    if scene.task != "strips":
        raise ConfigError(f"--scene: simulate takes a strip-array scene, {scene.name!r} is a {scene.task!r} scene")
    arrays = load_arrays(args.pressure)
    if "pressure" not in arrays:
        raise InputError(f"{args.pressure}: needs an array named 'pressure'")
    field = arrays["pressure"]
    sensor = StripSensor(scene.sensor)
    single = field.ndim == 2
    if single:
        field = field[None]
    gains = arrays.get("gains")
    out = sensor.forward(field, gains=gains, rng=np.random.default_rng(args.seed), noise=args.noise)
    if single:
        out = {k: v[0] for k, v in out.items()}
    atomic_save_npz(args.out, out)
    print(f"wrote {args.out}: readings {out['readings'].shape}, intersection map {out['pressure'].shape}")
    return 0
