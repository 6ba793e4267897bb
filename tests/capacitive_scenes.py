"""Tiny capacitive scenes for the tests: a 4 x 3 array (not square: catches transposes)."""

from __future__ import annotations

from typing import Any

from synth.scene import Scene, load_scene, parse_scene


def tiny_capacitive_scene(rows: int = 4, cols: int = 3, calibration: bool = False, **sections: dict[str, Any]) -> Scene:
    """capacitive8's design on ``rows x cols`` cells, short presses; ``sections`` update tables
    (``readout={"drift_v": 0.0}``, ``stimuli={...}``, ``device={...}``)."""
    data = load_scene("capacitive8").to_dict()
    data["name"] = "tiny_capacitive"
    cap = data["capacitive"]
    if not calibration:
        cap.pop("calibration", None)
    cap["geometry"].update(n_rows=rows, n_cols=cols)
    cap["stimuli"].update(frames=6, count=[1, 1], margin_mm=1.0, pair_distance_mm=[0.0, 0.0], empty_fraction=0.0)
    for name, values in sections.items():
        cap[name].update(values)
    return parse_scene(data, "tiny_capacitive")


def calibration_rig(scene: Scene, frames: int = 10) -> Scene:
    """A probe on every cell of ``scene``'s device, load-unload cycles (capacitive8_rig's rig)."""
    data = scene.to_dict()
    rig = load_scene("capacitive8_rig").to_dict()["capacitive"]["stimuli"]
    data["capacitive"]["stimuli"] = {**rig, "frames": frames}
    data["capacitive"].pop("calibration", None)
    data["name"] = f"{scene.name}_rig"
    return parse_scene(data, data["name"])
