"""The sensor-model contract: one physics operator per sensor, its stimuli drawn apart from it.

Modelled on deepinv's ``Physics`` (``forward = sensor(noise(A(x)))``) and ``PhysicsGenerator``:

* a :class:`SensorModel` maps a *stimulus* (contacts or a pressure field, objects touched, ...) to
  *readings* in stages, each callable alone so that tests can check the physics of one stage::

      physics(stimulus)       mechanics or heat transfer: the transducer's physical input
                              (stress at the strips, thermistor temperature, load on each FSR)
      transduce(physical)     the transducer and its front end: the clean analog signal
      noise(analog, rng)      additive analog noise
      adc(analog)             quantisation and the converter's range

  ``forward(stimulus, rng)`` chains them; ``forward(stimulus)`` (no generator) is the noise-free,
  unquantised signal, the deterministic operator ``A`` that consistency checks push estimates
  through. ``inverse_readout`` undoes the front end where it is invertible (readings -> physical).
* a :class:`StimulusGenerator` draws ``n`` stimuli from a scene's distributions (``draw``) and
  reports their latent parameters and the ground truth the estimators are judged against;
* :func:`simulate` is the one generic loop every sensor shares: draw -> forward -> the outputs the
  scene asks for, and nothing else; :class:`ModelSimulator` wraps it as a scene's
  :class:`~synth.sensors.base.Simulator` (what ``make_simulator`` returns for the dataset writer).

A stimulus may be a sequence: a press of ``F`` frames is one stimulus whose arrays carry a frames
axis after the batch axis, and a stage with memory (a dielectric's hysteresis) carries its state
along that axis inside one call, starting from rest; calls stay independent of each other.

A stimulus is a frozen dataclass of batch-first arrays owned by its sensor module; per-sample
sensor variation (part-to-part gains, a touch's heater power) travels in the stimulus, drawn by the
generator, so that the model itself is a pure function of (stimulus, rng).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, Generic, TypeVar

import numpy as np

from synth.sensors.base import ArraySpec

__all__ = ["ModelSimulator", "SensorModel", "StimulusGenerator", "StimulusT", "simulate", "stored_readings"]

StimulusT = TypeVar("StimulusT")


class SensorModel(ABC, Generic[StimulusT]):
    """A sensor's forward operator in stages (see the module docstring)."""

    #: the stages in the order ``forward`` applies them (documentation and conformance tests)
    stages: tuple[str, ...] = ("physics", "transduce", "noise", "adc")
    #: readings are ADC codes even without noise (the FSR's): a dataset without noise stores
    #: ``adc(forward(stimulus))``, not the clean signal (:func:`stored_readings`)
    codes_without_noise: bool = False

    @abstractmethod
    def physics(self, stimulus: StimulusT) -> np.ndarray:
        """Mechanics or heat transfer: the transducer's physical input, batch first, float64."""

    @abstractmethod
    def transduce(self, physical: np.ndarray, stimulus: StimulusT) -> np.ndarray:
        """The transducer and its front end: clean analog readings, batch first, float64.
        ``stimulus`` carries any per-sample sensor variation (gains) the generator drew."""

    @abstractmethod
    def noise(self, analog: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Analog readings with their noise added (a new array)."""

    @abstractmethod
    def adc(self, analog: np.ndarray) -> np.ndarray:
        """Quantised readings clipped to the converter's range."""

    def forward(self, stimulus: StimulusT, rng: np.random.Generator | None = None) -> np.ndarray:
        """Readings of ``stimulus``: noisy and quantised with ``rng``, the clean signal without."""
        clean = self.transduce(self.physics(stimulus), stimulus)
        if rng is None:
            return clean
        return self.adc(self.noise(clean, rng))

    def inverse_readout(self, readings: np.ndarray) -> np.ndarray:
        """The physical input that gives ``readings`` (the front end inverted); not every sensor has one."""
        raise NotImplementedError(f"{type(self).__name__} has no readout inverse")

    @abstractmethod
    def reading_spec(self) -> ArraySpec:
        """Per-sample shape and dtype of the readings as stored (the dataset's ``readings``)."""


class StimulusGenerator(ABC, Generic[StimulusT]):
    """Draws stimuli from a scene's distributions; reports what an estimator is judged against."""

    @abstractmethod
    def draw(self, n: int, rng: np.random.Generator) -> StimulusT:
        """``n`` stimuli; the same generator state gives the same stimuli."""

    @abstractmethod
    def truth(self, stimulus: StimulusT, wanted: tuple[str, ...]) -> dict[str, np.ndarray]:
        """The wanted ground-truth and latent arrays of ``stimulus`` (only those; batch first).
        ``wanted`` names every output the scene asks for, ``readings`` included."""

    @abstractmethod
    def truth_specs(self, wanted: tuple[str, ...]) -> dict[str, ArraySpec]:
        """Per-sample shape and dtype of every array :meth:`truth` returns for ``wanted``."""


def stored_readings(model: SensorModel[Any], stimulus: Any, rng: np.random.Generator | None) -> np.ndarray:
    """What a dataset stores as ``model``'s readings: ``forward(stimulus, rng)``; without noise
    (``rng=None``) the clean signal, passed through the ADC for a sensor whose readings are codes
    whatever the noise (``SensorModel.codes_without_noise``)."""
    if rng is None and model.codes_without_noise:
        return model.adc(model.forward(stimulus))
    return model.forward(stimulus, rng)


def simulate(
    model: SensorModel[Any],
    generator: StimulusGenerator[Any],
    n: int,
    rng: np.random.Generator,
    wanted: tuple[str, ...],
    noise: bool = True,
    channels: dict[str, SensorModel[Any]] | None = None,
) -> dict[str, np.ndarray]:
    """The generic draw -> forward loop: ``n`` samples of the ``wanted`` outputs.

    ``readings`` are computed only when wanted; with ``noise`` they pass the noise and ADC stages
    (the generator's random stream is consumed by ``draw`` first, then by the noise, so the stimuli
    do not depend on whether noise is on). ``channels`` are further sensor models read on the same
    stimuli (a second thermistor beside the heated one), each an output of its own name, read after
    the readings in their order. The generator's truth follows (it is given every wanted output:
    a by-product of the readings, such as the clean readings, is stored only with them). Stored
    dtypes follow the specs.
    """
    stimulus = generator.draw(n, rng)
    out: dict[str, np.ndarray] = {}
    read_rng = rng if noise else None
    if "readings" in wanted:
        spec = model.reading_spec()
        out["readings"] = stored_readings(model, stimulus, read_rng).astype(spec.dtype, copy=False)
    for name, channel in (channels or {}).items():
        if name in wanted:
            spec = channel.reading_spec()
            out[name] = stored_readings(channel, stimulus, read_rng).astype(spec.dtype, copy=False)
    others = tuple(w for w in wanted if w != "readings" and w not in (channels or {}))
    if others:
        specs = generator.truth_specs(wanted)
        for key, value in generator.truth(stimulus, wanted).items():
            out[key] = np.asarray(value, dtype=specs[key].dtype)
    return out


class ModelSimulator:
    """A scene's simulator for a sensor on this contract: :func:`simulate` with the scene's wanted
    outputs and noise switch, and the specs of exactly those outputs."""

    def __init__(
        self,
        model: SensorModel[Any],
        generator: StimulusGenerator[Any],
        wanted: tuple[str, ...],
        noise: bool = True,
        channels: dict[str, SensorModel[Any]] | None = None,
    ) -> None:
        self.model = model
        self.generator = generator
        self.wanted = tuple(wanted)
        self.noise = noise
        self.channels = dict(channels or {})

    def output_specs(self) -> dict[str, ArraySpec]:
        specs: dict[str, ArraySpec] = {}
        if "readings" in self.wanted:
            specs["readings"] = self.model.reading_spec()
        for name, channel in self.channels.items():
            if name in self.wanted:
                specs[name] = channel.reading_spec()
        if any(w != "readings" and w not in self.channels for w in self.wanted):
            specs.update(self.generator.truth_specs(self.wanted))
        return specs

    def simulate(self, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        return simulate(self.model, self.generator, n, rng, self.wanted, self.noise, self.channels)
