"""The thermal fingertip as a :class:`~synth.sensors.model.SensorModel`: heat transfer -> thermistor
-> noise -> ADC (the physics in :mod:`synth.sensors.thermal.physics`, real sensors' channels in
:mod:`synth.sensors.thermal.touch`).

``physics`` gives every pixel's temperature over the record (degC, ``(B, P, R)`` float64): the
seed's heated pixel touching a semi-infinite object (the fast path of
:mod:`synth.sensors.thermal.fast`, or ``reference=True``: the whole-record closed form), or, for
real-sensor scenes, the lagging heated thermistor of :func:`~synth.sensors.thermal.touch.clean_channels`.
A thermistor reads its own temperature, so ``transduce`` is the identity; ``noise`` adds the
recorder's time-stamp jitter (real-sensor scenes) and the thermistor noise; ``adc`` quantises to
``adc_step_k`` and clips to ``adc_range_c``. :class:`PassiveModel` is the unheated thermistor
beside each pixel, read on the same touches.
"""

from __future__ import annotations

import numpy as np

from synth.sensors.base import ArraySpec
from synth.sensors.model import SensorModel
from synth.sensors.thermal.config import ThermalConfig
from synth.sensors.thermal.fast import record_excess
from synth.sensors.thermal.physics import ContactModel, touch_excess
from synth.sensors.thermal.readout import Readout
from synth.sensors.thermal.stimuli import OUTPUTS, Touches
from synth.sensors.thermal.touch import clean_channels, jitter

__all__ = ["PassiveModel", "ThermalModel"]

#: samples (touches x pixels x record) per block of :meth:`ThermalModel.forward`'s physics
_READOUT_BLOCK = 1_280_000
#: samples per pass of its noise and ADC (the block and its draws stay in the L2 cache)
_NOISE_BLOCK = 65_536


class ThermalModel(SensorModel[Touches]):
    """The heated thermistor array of a ``[thermal]`` table; readings ``(B, P, R)`` in degC.

    ``reference=True`` evaluates the contact solution on every sample of the record
    (:func:`~synth.sensors.thermal.physics.touch_excess`); the default computes only the samples
    that need it (:func:`~synth.sensors.thermal.fast.record_excess`, the same curve to rounding,
    ~10x faster). The channels of the last real-sensor stimulus are kept, so the passive channel
    read on the same touches does not repeat them.
    """

    def __init__(self, config: ThermalConfig, reference: bool = False) -> None:
        self.config = config
        self.reference = reference
        self.readout = Readout(config.readout)
        r = config.readout
        self.time_s = np.arange(r.n_samples) / r.sampling_hz
        self._last: tuple[Touches, tuple[np.ndarray, np.ndarray | None]] | None = None

    def channels(self, stimulus: Touches) -> tuple[np.ndarray, np.ndarray | None]:
        """Clean heated and passive readings (B, P, R) of a real-sensor scene (passive: ``None``
        when disabled)."""
        if self._last is None or self._last[0] is not stimulus:
            self._last = (stimulus, clean_channels(self.config, self.time_s, stimulus.params))
        return self._last[1]

    def physics(self, stimulus: Touches) -> np.ndarray:
        """Every pixel's temperature (degC) over the record, (B, P, R) float64."""
        if self.config.dynamic:
            return self.channels(stimulus)[0]
        n, p = stimulus["touched"].shape
        out = np.empty((n, p, len(self.time_s)))
        self._contact_into(stimulus, out)
        return out

    def _contact_into(self, stimulus: Touches, out: np.ndarray) -> None:
        """The seed model's temperatures (B, P, R) written into ``out``."""
        d = stimulus.params
        # pixels touching nothing sit at their steady state T_amb + Q/G
        steady = d["ambient"][:, None] + d["heater"] / d["loss"]
        out[:] = steady[..., None]
        sel = d["touched"]
        if sel.any():
            model = ContactModel.of_touched(d)
            excess = touch_excess if self.reference else record_excess
            v = excess(self.time_s, model, d["onset"][sel], d["release"][sel])
            v += d["object_c"][sel][:, None]  # in place: the same sum as object_c + v
            out[sel] = v

    def transduce(self, physical: np.ndarray, stimulus: Touches) -> np.ndarray:
        return physical  # a thermistor reads its own temperature (its lags are in the physics)

    def noise(self, analog: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        if self.config.dynamic:
            analog = jitter(analog, self.time_s, self.config.readout.timing_jitter_s, rng)
        return self.readout.noise(analog, rng)

    def adc(self, analog: np.ndarray) -> np.ndarray:
        return self.readout.adc(analog)

    def forward(self, stimulus: Touches, rng: np.random.Generator | None = None) -> np.ndarray:
        """As :meth:`SensorModel.forward`, a few touches at a time on the seed's fast path: blocks
        of ~60 touches keep the (touches, P, R) float64 temporaries in cache, and the noise of
        consecutive blocks is the same stream as one draw for all (the same bytes). Every stage
        writes into the output's block (one scratch array for the noise draws): no per-block
        allocation of a few MB (fresh pages: their faults cost about as much as the arithmetic)
        and no copy of the block into the output."""
        if self.config.dynamic or self.reference:
            return super().forward(stimulus, rng)
        n, p = stimulus["touched"].shape
        out = np.empty((n, p, len(self.time_s)))
        block = max(1, _READOUT_BLOCK // max(1, p * len(self.time_s)))
        scratch = np.empty(min(out.size, _NOISE_BLOCK)) if rng is not None else None
        for start in range(0, n, block):
            dest = out[start : start + block]
            self._contact_into(stimulus.take(slice(start, start + block)), dest)  # transduce: identity
            if rng is None or scratch is None:
                continue
            flat = dest.reshape(-1)  # a view (out is C-contiguous): the draws fill it in C order
            for at in range(0, len(flat), _NOISE_BLOCK):
                part = flat[at : at + _NOISE_BLOCK]
                self.readout.add_noise(part, scratch[: len(part)], rng)
                self.readout.adc(part, out=part)
        return out

    def reading_spec(self) -> ArraySpec:
        return ArraySpec((self.config.n_pixels, self.config.readout.n_samples), "float32", OUTPUTS["readings"])


class PassiveModel(SensorModel[Touches]):
    """The passive (unheated) thermistor beside every pixel of a real-sensor scene with
    ``[thermal.passive] enabled``: the same touches, its own lags and drift, the same readout."""

    def __init__(self, heated: ThermalModel) -> None:
        if not heated.config.passive.enabled:
            raise ValueError("the passive channel needs [thermal.passive] enabled = true")
        self.heated = heated
        self.config = heated.config

    def physics(self, stimulus: Touches) -> np.ndarray:
        passive = self.heated.channels(stimulus)[1]
        assert passive is not None  # enabled (checked above)
        return passive

    def transduce(self, physical: np.ndarray, stimulus: Touches) -> np.ndarray:
        return physical

    def noise(self, analog: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return self.heated.noise(analog, rng)

    def adc(self, analog: np.ndarray) -> np.ndarray:
        return self.heated.adc(analog)

    def reading_spec(self) -> ArraySpec:
        return ArraySpec((self.config.n_pixels, self.config.readout.n_samples), "float32", OUTPUTS["passive"])
