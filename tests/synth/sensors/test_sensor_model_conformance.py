"""Every sensor model against the contract of ``synth.sensors.model``: shapes and dtypes,
determinism, ``forward`` as the stages chained, zero stimulus -> the baseline, monotone where the
physics says, the noise stage's spread, the ADC's range, the readout inverse, and the scene's
simulator as the generic draw -> forward loop over the same stages."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from synth.scene import Scene, load_scene, parse_scene
from synth.sensors import sensor_model, sensor_module
from synth.sensors.capacitive import CapacitiveModel, Presses
from synth.sensors.fsr import FsrModel, FsrPresses
from synth.sensors.model import SensorModel, StimulusGenerator
from synth.sensors.strips import ContactGenerator, PressureField, StripModel
from synth.sensors.thermal import PassiveModel, ThermalModel, Touches, TouchGenerator, make_simulator


@dataclass
class Case:
    """One sensor: its scene, how to draw stimuli, a stimulus with nothing touching, and a pair of
    stimuli ``(weak, strong)`` whose readings the physics orders (``strong >= weak``, strictly
    somewhere), with the noise s.d. the noise stage must add."""

    scene: str
    generator: Callable[[SensorModel[Any]], StimulusGenerator[Any]]
    nothing: Callable[[SensorModel[Any]], Any]
    ordered: Callable[[SensorModel[Any]], tuple[Any, Any]]
    noise_sd: Callable[[SensorModel[Any]], float]


def _strip_field(model: StripModel, scale: float) -> PressureField:
    g = model.config.geometry
    shape = (g.n_rows * g.samples_per_pitch, g.n_cols * g.samples_per_pitch)
    y, x = np.mgrid[: shape[0], : shape[1]]
    bump = np.exp(-((y - shape[0] / 3) ** 2 + (x - shape[1] / 2) ** 2) / 20.0)  # one soft press
    return PressureField.from_field(scale * 40.0 * bump[None].repeat(2, axis=0), model.config)


def _fsr_presses(force: float) -> FsrPresses:
    xy = np.array([[0.0, 0.0], [-10.0, 5.77], [25.0, -20.0]])  # centre, on a disc, off the triangles
    return FsrPresses.from_contacts(xy, np.full(3, force), 4.0)


def _capacitive_field(model: CapacitiveModel, scale: float) -> Presses:
    hp, wp = model.config.geometry.lattice_shape
    y, x = np.mgrid[:hp, :wp]
    bump = np.exp(-((y - hp / 2) ** 2 + (x - wp / 3) ** 2) / 30.0)
    frames = np.linspace(0.2, 1.0, model.frames)[:, None, None]
    return Presses.from_field(scale * 60.0 * frames * bump[None, None].repeat(2, axis=0), model.config)


def _thermal_touches(model: ThermalModel, object_c: Any, touched: bool = True) -> Touches:
    p = model.config.n_pixels
    return Touches.from_objects(
        model.config,
        object_c=object_c,
        k_w_mk=[15.0, 0.2],  # steel-like and wood-like
        rho_kg_m3=[7900.0, 600.0],
        c_j_kgk=[500.0, 1700.0],
        conductance_w_m2k=10000.0,
        radius_mm=5.0,
        onset_s=2.6,
        contact_s=2.5,
        touched=np.full((2, p), touched),
    )


CASES = {
    "strips": Case(
        "strips5",
        lambda m: ContactGenerator(m.config, m),  # type: ignore[attr-defined]
        lambda m: _strip_field(m, 0.0),  # type: ignore[arg-type]
        lambda m: (_strip_field(m, 1.0), _strip_field(m, 2.0)),  # type: ignore[arg-type]
        lambda m: m.config.readout.noise_v,  # type: ignore[attr-defined]
    ),
    "strips-diagonal": Case(
        "strips16_twins_diagonal",
        lambda m: ContactGenerator(m.config, m),  # type: ignore[attr-defined]
        lambda m: _strip_field(m, 0.0),  # type: ignore[arg-type]
        lambda m: (_strip_field(m, 1.0), _strip_field(m, 2.0)),  # type: ignore[arg-type]
        lambda m: m.config.readout.noise_v,  # type: ignore[attr-defined]
    ),
    "fsr": Case(
        "fsr6",
        lambda m: sensor_module("fsr").PressGenerator(m.config, m),  # type: ignore[attr-defined]
        lambda m: _fsr_presses(0.0),
        lambda m: (_fsr_presses(2.0), _fsr_presses(6.0)),
        lambda m: m.config.readout.noise_lsb,  # type: ignore[attr-defined]
    ),
    "capacitive": Case(
        "capacitive8",
        lambda m: sensor_module("capacitive").PressGenerator(m.config, m),  # type: ignore[attr-defined]
        lambda m: _capacitive_field(m, 0.0),  # type: ignore[arg-type]
        lambda m: (_capacitive_field(m, 1.0), _capacitive_field(m, 2.0)),  # type: ignore[arg-type]
        lambda m: m.noise_v,  # type: ignore[attr-defined]
    ),
    "thermal": Case(
        "thermal",
        lambda m: sensor_module("thermal").TouchGenerator(m.config),  # type: ignore[attr-defined]
        lambda m: _thermal_touches(m, 15.0, touched=False),  # type: ignore[arg-type]
        # a warmer object draws less heat from the heated pixel: its reading stays higher
        lambda m: (_thermal_touches(m, [12.0, 12.0]), _thermal_touches(m, [20.0, 20.0])),  # type: ignore[arg-type]
        lambda m: m.config.readout.noise_k,  # type: ignore[attr-defined]
    ),
}
NAMES = list(CASES)


@pytest.fixture(params=NAMES)
def case(request: pytest.FixtureRequest) -> tuple[str, Case, Scene, SensorModel[Any]]:
    name = request.param
    scene = load_scene(CASES[name].scene)
    return name, CASES[name], scene, sensor_model(scene)


def _draw(case: tuple[str, Case, Scene, SensorModel[Any]], n: int = 6, seed: int = 3) -> Any:
    _, c, _, model = case
    return c.generator(model).draw(n, np.random.default_rng(seed))


def test_the_factory_gives_each_task_its_model(case: tuple[str, Case, Scene, SensorModel[Any]]) -> None:
    name, _, _, model = case
    expected = {"strips": StripModel, "fsr": FsrModel, "capacitive": CapacitiveModel, "thermal": ThermalModel}
    assert type(model) is expected[name.split("-")[0]]
    assert model.stages == ("physics", "transduce", "noise", "adc")


def test_readings_shape_and_dtype(case: tuple[str, Case, Scene, SensorModel[Any]]) -> None:
    _, _, _, model = case
    stimulus = _draw(case)
    spec = model.reading_spec()
    readings = model.forward(stimulus, np.random.default_rng(0))
    assert readings.shape == (len(stimulus), *spec.shape)
    assert np.isfinite(readings).all()
    assert readings.astype(spec.dtype).dtype == np.dtype(spec.dtype)
    clean = model.forward(stimulus)
    assert clean.shape == readings.shape and np.isfinite(clean).all()


def test_same_seed_same_readings(case: tuple[str, Case, Scene, SensorModel[Any]]) -> None:
    _, c, _, model = case
    a = _draw(case, seed=5)
    b = _draw(case, seed=5)
    other = _draw(case, seed=6)
    ra, rb = model.forward(a, np.random.default_rng(1)), model.forward(b, np.random.default_rng(1))
    assert np.array_equal(ra, rb)
    assert not np.array_equal(ra, model.forward(other, np.random.default_rng(1)))
    # a user's stimulus (no noise drawn with it): another noise seed gives other readings
    weak, _ = c.ordered(model)
    assert not np.array_equal(
        model.forward(weak, np.random.default_rng(1)), model.forward(weak, np.random.default_rng(2))
    )


def test_forward_is_the_stages_chained(case: tuple[str, Case, Scene, SensorModel[Any]]) -> None:
    _, c, _, model = case
    for stimulus in (_draw(case), c.ordered(model)[1]):
        clean = model.transduce(model.physics(stimulus), stimulus)
        assert np.array_equal(model.forward(stimulus), clean)
    weak, _ = c.ordered(model)  # no noise draws of its own: the noise stage draws from rng
    clean = model.transduce(model.physics(weak), weak)
    chained = model.adc(model.noise(clean, np.random.default_rng(9)))
    assert np.array_equal(model.forward(weak, np.random.default_rng(9)), chained)


def test_the_simulator_is_the_generic_loop_over_the_stages(case: tuple[str, Case, Scene, SensorModel[Any]]) -> None:
    """What datasets hold (the simulator, on a seed) is the stages of a fresh model applied by hand
    to the stimuli drawn on the same seed: the same bytes, noise on and off."""
    name, c, scene, _ = case
    for noise in (True, False):
        sim = sensor_module(scene.task).make_simulator(scene.with_noise(noise))
        out = sim.simulate(5, np.random.default_rng(17))
        model = sensor_model(scene)
        rng = np.random.default_rng(17)
        generator = c.generator(model)
        if name == "fsr" and not noise:
            generator.noise = False  # type: ignore[attr-defined]
        stimulus = generator.draw(5, rng)
        clean = model.transduce(model.physics(stimulus), stimulus)
        if not noise:
            expected = model.adc(clean) if model.codes_without_noise else clean
        elif name == "fsr":  # the ADC noise was drawn with the stimulus
            expected = model.adc(model.add_noise(clean, stimulus.adc_noise))  # type: ignore[attr-defined]
        else:
            expected = model.adc(model.noise(clean, rng))
        assert out["readings"].dtype == np.dtype(model.reading_spec().dtype)
        assert np.array_equal(out["readings"], expected.astype(model.reading_spec().dtype))


def test_nothing_touching_reads_the_baseline(case: tuple[str, Case, Scene, SensorModel[Any]]) -> None:
    name, c, _, model = case
    nothing = c.nothing(model)
    physical = model.physics(nothing)
    clean = model.forward(nothing)
    if name == "thermal":  # every pixel at its steady state T_amb + Q/G over the whole record
        steady = nothing["ambient"][:, None] + nothing["heater"] / nothing["loss"]
        assert np.allclose(clean, steady[..., None], rtol=0, atol=1e-12)
        return
    assert not physical.any()  # no stress, no load
    if name.startswith("strips"):  # an unloaded strip reads exactly the amplifier's offset
        assert np.all(clean == np.float32(model.config.readout.offset_v))  # type: ignore[attr-defined]
    elif name == "fsr":  # only the leak conductance
        leak = model.readout.codes(np.full((1, 6), model.config.element.leak_conductance_us))  # type: ignore[attr-defined]
        assert np.array_equal(model.adc(clean), np.broadcast_to(leak, clean.shape))
    else:  # at rest over every frame: the same reading in every frame
        assert np.array_equal(clean, np.broadcast_to(clean[:, :1], clean.shape))


def test_readings_are_monotone_where_the_physics_says(case: tuple[str, Case, Scene, SensorModel[Any]]) -> None:
    """More force -> more strip / FSR / capacitive signal; a colder object -> a lower heated reading."""
    _, c, _, model = case
    weak, strong = c.ordered(model)
    a, b = model.forward(weak), model.forward(strong)
    assert np.all(b >= a - 1e-9)
    assert np.any(b > a + 1e-6)


def test_noise_stage_adds_its_spread(case: tuple[str, Case, Scene, SensorModel[Any]]) -> None:
    _, c, _, model = case
    clean = np.asarray(model.forward(c.ordered(model)[1]))
    reps = max(1, 40_000 // clean.size)
    big = np.concatenate([clean] * reps)
    noisy = model.noise(big, np.random.default_rng(4))
    assert noisy.shape == big.shape and noisy is not big
    sd = float(np.std(noisy.astype(np.float64) - big))
    assert sd == pytest.approx(c.noise_sd(model), rel=0.05)
    assert np.array_equal(model.noise(big, np.random.default_rng(4)), noisy)


def test_adc_clips_to_its_range_and_is_idempotent(case: tuple[str, Case, Scene, SensorModel[Any]]) -> None:
    _, c, _, model = case
    clean = np.asarray(model.forward(c.ordered(model)[1]), dtype=np.float64)
    span = float(np.abs(clean).max()) + 1.0
    top, bottom = model.adc(clean * 0 + 1e3 * span), model.adc(clean * 0 - 1e3 * span)
    assert np.array_equal(model.adc(clean * 0 + 1e6 * span), top)  # saturated: further up reads the same
    assert np.array_equal(model.adc(clean * 0 - 1e6 * span), bottom)
    codes = model.adc(clean)
    assert np.all((codes >= bottom) & (codes <= top))
    assert np.array_equal(model.adc(codes), codes)
    assert len(np.unique(model.adc(np.linspace(clean.min(), clean.max(), 10_000)))) < 10_000  # quantised


def test_inverse_readout_round_trips_where_it_exists(case: tuple[str, Case, Scene, SensorModel[Any]]) -> None:
    name, c, _, model = case
    _, strong = c.ordered(model)
    physical = model.physics(strong)
    if name == "thermal":  # a thermistor reads its own temperature: there is nothing to invert
        with pytest.raises(NotImplementedError):
            model.inverse_readout(model.forward(strong))
        return
    back = model.inverse_readout(model.forward(strong))
    if name.startswith("strips"):  # channel loads in segment units, for the unit gains of a PressureField
        expected = model.sensor.channel_loads(physical, 1.0)  # type: ignore[attr-defined]
        assert np.allclose(back, expected, rtol=1e-3, atol=1e-6)
    elif name == "fsr":  # codes -> disc loads of a nominal film, each code at the centre of its bin
        codes = model.adc(model.forward(strong))
        lo, hi = model.inverse_readout(codes - 1), model.inverse_readout(codes + 1)
        above = physical > 3 * model.config.element.break_force_n  # type: ignore[attr-defined]
        assert above.any()  # below the break force the law is flat: nothing to invert
        assert np.all((lo[above] <= physical[above]) & (physical[above] <= hi[above]))
        assert np.all(lo[above] < hi[above])
    else:
        assert np.allclose(back, physical, rtol=1e-4, atol=1e-6)


#: a real fingertip (lagging thermistors, a held heater, drift, build-up, time-stamp jitter and a
#: passive thermistor): the heated channel and the passive one are sensor models of their own
REAL = {
    "name": "real",
    "task": "thermal",
    "outputs": ["readings", "passive", "latent"],
    "thermal": {
        "grid": [2, 2],
        "window_s": 6.0,
        "channels": ["heated", "passive"],
        "sensor": {"lag_s": [0.6, 0.9], "lag2_s": [0.3, 0.6], "heater": "constant", "set_point_c": [29.0, 30.0]},
        "contact": {"onset_s": [2.5, 3.0], "contact_s": [9.0, 9.0], "ramp_s": [0.0, 0.3]},
        "passive": {"enabled": True},
        "readout": {"sampling_hz": 25.0, "duration_s": 8.0, "timing_jitter_s": 0.002},
    },
}


def test_real_sensor_channels_follow_the_contract() -> None:
    scene = parse_scene(REAL, "real")
    heated = ThermalModel(scene.sensor)
    passive = PassiveModel(heated)
    touches = TouchGenerator(scene.sensor).draw(6, np.random.default_rng(2))
    for model in (heated, passive):
        spec = model.reading_spec()
        clean = model.transduce(model.physics(touches), touches)
        assert clean.shape == (6, *spec.shape) and np.isfinite(clean).all()
        assert np.array_equal(model.forward(touches), clean)
        a, b = model.forward(touches, np.random.default_rng(5)), model.forward(touches, np.random.default_rng(5))
        assert np.array_equal(a, b) and not np.array_equal(a, clean)
    # the simulator reads the heated channel, then the passive one, from one stream after the draw
    out = make_simulator(scene).simulate(6, np.random.default_rng(2))
    rng = np.random.default_rng(2)
    touches = TouchGenerator(scene.sensor).draw(6, rng)
    heated, passive = ThermalModel(scene.sensor), PassiveModel(heated)
    for name, model in (("readings", heated), ("passive", passive)):
        expected = model.adc(model.noise(model.transduce(model.physics(touches), touches), rng))
        assert np.array_equal(out[name], expected.astype(np.float32))
