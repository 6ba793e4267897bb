"""``tactile-learn calibrate --task thermal``: fit a user's fingertip from labelled recordings and
write its scene (the real-sensor model of :mod:`tactile_learn.calibration.thermal_scene`, or the
seed's of :mod:`tactile_learn.calibration.thermal_seed`)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from synth.config import dumps_toml
from synth.errors import ConfigError, DataError
from synth.io import atomic_write_text
from synth.scene import Scene, parse_scene
from tactile_learn.tasks.thermal_classes import thermal_config

__all__ = ["calibrate_thermal", "residual_headline"]

#: the residual's figures a terminal summary shows; the report file holds the rest (windows, kinks, ...)
HEADLINE_KEYS = ("rms_k", "rms_sigma", "within_3_sigma")


def residual_headline(residual: dict[str, Any]) -> dict[str, Any]:
    """The calibration report's residual cut to its headline: overall and per channel RMS (kelvin and
    noise sigma) and whether it is within 3 sigma; per-window, per-kink and per-touch detail stays in
    the report (printing it all gave a user 368 lines)."""
    out: dict[str, Any] = {k: residual[k] for k in HEADLINE_KEYS if k in residual}
    for channel in ("heated", "passive"):
        if isinstance(residual.get(channel), dict):
            out[channel] = {k: v for k, v in residual[channel].items() if k in HEADLINE_KEYS}
    return out


def calibrate_thermal(
    source: str | Path,
    out: str | Path,
    scene: Scene,
    channels: str | None = None,
    class_map: dict[str, tuple[str, ...]] | None = None,
) -> dict[str, Any]:
    """Fit the user's sensor from labelled recordings; write a scene TOML for ``generate``.

    Recordings of a real fingertip (a ``passive_c`` or ``force`` column, labels that are
    families or classes, a real-sensor scene, or ``channels`` given) get the real-sensor model
    (:func:`tactile_learn.calibration.thermal_scene.calibrate_recordings`: lags, heater, drift, contact
    build-up, passive channel; the report goes to ``out`` with the suffix ``.json``); plain
    single-material recordings of a seed-like sensor get the seed's model
    (:func:`~tactile_learn.calibration.thermal_seed.calibrate_sensor`). Either way the
    scene is validated before it is written, atomically: a failed calibration writes nothing."""
    from tactile_learn.thermal_recordings import read_recordings

    cfg = thermal_config(scene)
    touches = [t for t in read_recordings(source, class_map=class_map) if t.material]
    if not touches:
        raise DataError(f"{source}: no labelled touches to calibrate from")
    names = {m.name for m in cfg.material_list}
    real = (
        channels is not None
        or class_map is not None
        or cfg.dynamic
        or any(t.passive_c is not None or t.force is not None for t in touches)
        or any(t.material not in names for t in touches)
    )
    if real:
        from synth.io import atomic_write_json
        from tactile_learn.calibration.thermal_scene import CHANNEL_CHOICES, calibrate_recordings, write_scene

        has_passive = all(t.passive_c is not None for t in touches)
        chosen = CHANNEL_CHOICES[channels or ("all" if has_passive else "heated")]
        calibrated_scene, report = calibrate_recordings(source, chosen, class_map, name=f"{scene.name}_calibrated")
        write_scene(calibrated_scene, out, report)
        report_path = Path(out).with_suffix(".json")
        atomic_write_json(report_path, report)
        return {
            "scene": str(out),
            "report": str(report_path),
            "touches": len(touches),
            "classes": list(calibrated_scene.sensor.class_names),
            "residual": residual_headline(report["residual"]),
            "at_bound": report["at_bound"],
            "not_identified": report["not_identified"],
            "seconds": report["solver"]["seconds"],
        }
    from tactile_learn.calibration.thermal_seed import calibrate_sensor

    fitted, summary = calibrate_sensor(touches, cfg)
    calibrated = dataclasses.replace(
        scene,
        sensor=fitted,
        name=f"{scene.name}_calibrated",
        description=f"{scene.description} (sensor calibrated from {len(touches)} touches)".strip(),
    )
    text = dumps_toml(calibrated.to_dict())
    try:  # the scene must load back before it is written
        parse_scene(calibrated.to_dict(), str(out))
    except ConfigError as exc:
        raise DataError(
            f"{out}: the calibrated scene does not validate ({exc}); nothing written: calibrate with more, "
            "longer or cleaner touches, or give the onsets (touches.csv column onset_s)"
        ) from None
    header = "# Written by `tactile-learn calibrate --task thermal`: the sensor's own parameters.\n"
    atomic_write_text(out, header + text)
    return {"scene": str(out), "touches": len(touches), **summary}
