"""Touches of which only some pixels are read: simulate what a consumer reads, not the whole array.

The thermal classifier reads one pixel's curve at a time, and training reads a few random pixels
of every touch (pixels on one object are alike; more touches per step teach more than more pixels
of one touch). Simulating the other pixels of a ``4 x 4`` array is work nobody reads: a stream
that trains on 4 pixels per touch needs a quarter of the physics, noise and ADC.

:class:`PixelSubset` draws the scene's touches exactly as :class:`TouchGenerator` does (the same
random stream, so the touches are the scene's), then keeps ``pixels`` of each touch's pixels,
chosen uniformly without replacement from a further draw of the same generator. Every per-pixel
quantity (``(B, P)`` parameters, latents) keeps the chosen pixels in the order chosen; per-touch
quantities (``ambient``) are unchanged. The sensor models run on any number of pixels, so the
readings are ``(B, pixels, R)``: the same distribution of pixel curves as the full array's, at
``pixels / P`` of the cost.
"""

from __future__ import annotations

import numpy as np

from synth.errors import ConfigError
from synth.scene import Scene
from synth.sensors.base import ArraySpec
from synth.sensors.model import ModelSimulator, SensorModel, StimulusGenerator
from synth.sensors.thermal.config import ThermalConfig
from synth.sensors.thermal.sensor import PassiveModel, ThermalModel
from synth.sensors.thermal.stimuli import Touches, TouchGenerator

__all__ = ["PixelSubset", "PixelSubsetSimulator", "take_pixels"]


def take_pixels(touches: Touches, index: np.ndarray) -> Touches:
    """The pixels ``index`` (B, k) of every touch: per-pixel arrays (B, P, ...) gathered along the
    pixel axis, per-touch arrays (B,) kept."""
    n, p = touches["touched"].shape
    index = np.asarray(index)
    if index.ndim != 2 or len(index) != n or (index.size and (index.min() < 0 or index.max() >= p)):
        raise ValueError(f"pixel index: expected ({n}, k) indices in [0, {p}), got shape {index.shape}")
    params: dict[str, np.ndarray] = {}
    for name, values in touches.params.items():
        if values.ndim >= 2 and values.shape[:2] == (n, p):
            params[name] = np.take_along_axis(values, index.reshape(n, -1, *([1] * (values.ndim - 2))), axis=1)
        elif values.shape[:1] == (n,) and values.ndim == 1:
            params[name] = values
        else:  # a new kind of parameter: say so rather than guess its axes
            raise ValueError(f"touch parameter {name!r}: shape {values.shape} is neither (B,) nor (B, P, ...)")
    return Touches(params)


class PixelSubset(StimulusGenerator[Touches]):
    """The scene's touches, ``pixels`` random pixels of each (see the module docstring)."""

    def __init__(self, config: ThermalConfig, pixels: int) -> None:
        if isinstance(pixels, bool) or not isinstance(pixels, int) or not 1 <= pixels <= config.n_pixels:
            raise ConfigError(f"pixels: expected an integer from 1 to the array's {config.n_pixels}, got {pixels!r}")
        self.config = config
        self.pixels = pixels
        self.touches = TouchGenerator(config)

    def draw(self, n: int, rng: np.random.Generator) -> Touches:
        touches = self.touches.draw(n, rng)  # first: the scene's touches, from the scene's stream
        if self.pixels == self.config.n_pixels:
            return touches
        pick = np.argsort(rng.random((n, self.config.n_pixels)), axis=1)[:, : self.pixels]
        return take_pixels(touches, pick)

    def truth_specs(self, wanted: tuple[str, ...]) -> dict[str, ArraySpec]:
        return {k: _with_pixels(s, self.pixels) for k, s in self.touches.truth_specs(wanted).items()}

    def truth(self, stimulus: Touches, wanted: tuple[str, ...]) -> dict[str, np.ndarray]:
        return self.touches.truth(stimulus, wanted)


def _with_pixels(spec: ArraySpec, pixels: int) -> ArraySpec:
    return ArraySpec((pixels, *spec.shape[1:]), spec.dtype, spec.description)


class _SubsetChannel(SensorModel[Touches]):
    """A channel's model whose readings spec counts the pixels read (the physics is the model's)."""

    def __init__(self, model: SensorModel[Touches], pixels: int) -> None:
        self.model = model
        self.pixels = pixels
        self.codes_without_noise = model.codes_without_noise

    def physics(self, stimulus: Touches) -> np.ndarray:
        return self.model.physics(stimulus)

    def transduce(self, physical: np.ndarray, stimulus: Touches) -> np.ndarray:
        return self.model.transduce(physical, stimulus)

    def noise(self, analog: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return self.model.noise(analog, rng)

    def adc(self, analog: np.ndarray) -> np.ndarray:
        return self.model.adc(analog)

    def forward(self, stimulus: Touches, rng: np.random.Generator | None = None) -> np.ndarray:
        return self.model.forward(stimulus, rng)

    def reading_spec(self) -> ArraySpec:
        return _with_pixels(self.model.reading_spec(), self.pixels)


class PixelSubsetSimulator(ModelSimulator):
    """A thermal scene's simulator that reads ``pixels`` random pixels of every touch: outputs as the
    scene's (readings, passive, latents), with ``pixels`` in place of the array's pixel count."""

    def __init__(self, scene: Scene, pixels: int) -> None:
        config: ThermalConfig = scene.sensor
        generator = PixelSubset(config, pixels)
        heated = ThermalModel(config)
        channels: dict[str, SensorModel[Touches]] = {}
        if config.passive.enabled:
            channels["passive"] = _SubsetChannel(PassiveModel(heated), pixels)
        super().__init__(_SubsetChannel(heated, pixels), generator, scene.outputs, scene.noise, channels)
        self.scene = scene
        self.pixels = pixels
