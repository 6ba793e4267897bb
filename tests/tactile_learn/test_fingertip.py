"""The combined fingertip: episode simulation, and the pipeline that runs the thermal classifier only
on thermistors under a contact."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from synth.dataset import simulate_shard
from synth.scene import Scene, load_scene
from synth.sensors.fingertip import press_profile
from tactile_learn.estimators.base import Estimator
from tactile_learn.fingertip import FingertipPipeline, _windows


@cache
def episodes() -> tuple[Scene, dict[str, np.ndarray]]:
    scene = load_scene("fingertip")
    return scene, simulate_shard(scene, 21, 0, 6)


class CountingClassifier(Estimator):
    """Stands in for the thermal model: records what it is asked, answers material 1."""

    def __init__(self, classes: int) -> None:
        self.classes = classes
        self.calls: list[int] = []

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        self.calls.append(len(X))
        out = np.zeros((len(X), self.classes), dtype=np.float32)
        out[:, 1] = 1.0
        return out


def test_press_profile_ramps_between_onset_and_release() -> None:
    t = np.arange(0, 5, 0.1)
    load = press_profile(t, np.array([[1.0]]), np.array([[3.0]]), 0.3)[0, :, 0]
    assert (load[t < 1.0] == 0).all() and (load[t >= 3.0] == 0).all()
    assert load[np.isclose(t, 2.0)] == 1.0
    assert 0 < load[np.isclose(t, 1.1)][0] < 1 and 0 < load[np.isclose(t, 2.9)][0] < 1


def test_episodes_are_consistent() -> None:
    scene, data = episodes()
    cfg = scene.sensor
    f, p = cfg.frames, cfg.thermal.n_pixels
    assert data["readings"].shape == (6, f, 8, 8) and data["thermal_readings"].shape == (6, p, 325)
    contact = data["thermistor_contact"]
    # a thermistor in contact shows a material; none is touched before the earliest onset
    shows = np.broadcast_to(data["thermistor_material"][:, None, :] >= 0, contact.shape)
    assert shows[contact].all()
    first = data["latent_onset_s"].min(axis=1)
    before = cfg.frame_times_s[None, :] < first[:, None]
    assert not contact[before].any() and contact.any()
    again = simulate_shard(scene, 21, 0, 6)
    assert all(np.array_equal(data[k], again[k]) for k in data)


def test_thermal_runs_only_under_contact_and_never_on_idle_frames() -> None:
    scene, data = episodes()
    pipe = FingertipPipeline(scene, capacitive_method="bicubic").fit()
    pipe.thermal_ = stub = CountingClassifier(pipe.none_class_ + 1)
    frames = pipe.run(data["readings"][0], data["thermal_readings"][0])
    under = np.array([f.classified for f in frames])
    assert len(stub.calls) == under.any(axis=1).sum()  # one call per frame with contact, none otherwise
    assert stub.calls == [int(row.sum()) for row in under if row.any()]
    assert under.any() and not under.all()
    since = np.zeros(16)
    for fr in frames:
        covered = (fr.mask[None] & pipe.footprints_).sum(axis=(1, 2)) / pipe.footprints_[0].sum()
        touching = covered >= scene.sensor.coverage
        since = np.where(touching, since + 1, 0)  # frames in contact, this one included
        # classified: under contact for at least min_contact_s (0.2 s: the third frame at 10 Hz)
        assert np.array_equal(fr.classified, touching & (since >= 3))
        assert ((fr.material_map >= 0) == (fr.mask & pipe.footprints_[fr.classified].any(axis=0))).all()
        assert (fr.material_map[fr.material_map >= 0] == 1).all()
    everything = FingertipPipeline(scene, capacitive_method="bicubic", skip=False).fit()
    everything.thermal_ = every = CountingClassifier(pipe.none_class_ + 1)
    frames_all = everything.run(data["readings"][0], data["thermal_readings"][0])
    assert every.calls == [16] * len(frames_all)
    assert all(np.array_equal(a.material_map, b.material_map) for a, b in zip(frames, frames_all, strict=True))


def test_skipping_leaves_the_shipped_classifiers_answers_unchanged() -> None:
    scene, data = episodes()
    skip = FingertipPipeline(scene, capacitive_method="bicubic").fit()
    full = FingertipPipeline(scene, capacitive_method="bicubic", skip=False).fit()
    for e in range(2):
        a = skip.run(data["readings"][e], data["thermal_readings"][e])
        b = full.run(data["readings"][e], data["thermal_readings"][e])
        for fa, fb in zip(a, b, strict=True):
            assert np.array_equal(fa.thermistor_material, fb.thermistor_material)
    # and it names the materials of the thermistors it found under contact, once in contact for 1 s
    frames = [fr for e in range(6) for fr in skip.run(data["readings"][e], data["thermal_readings"][e])]
    pred = np.array([fr.thermistor_material for fr in frames]).reshape(6, -1, 16)
    truth = np.broadcast_to(data["thermistor_material"][:, None, :], pred.shape)
    onset = data["latent_onset_s"].max(axis=1)[:, None, None]
    late = data["thermistor_contact"] & (scene.sensor.frame_times_s[None, :, None] >= onset + 1.0) & (pred >= 0)
    assert late.sum() > 20 and (pred[late] == truth[late]).mean() > 0.9


def test_windows_end_at_the_frames_sample() -> None:
    record = np.arange(20, dtype=np.float32)[None, :].repeat(2, axis=0)
    w = _windows(record, 5, 8)  # samples 0..5, the first repeated before the record starts
    assert w.shape == (2, 8) and w[0].tolist() == [0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    assert _windows(record, 12, 4)[1].tolist() == [9.0, 10.0, 11.0, 12.0]


def test_pipeline_refuses_an_unknown_method() -> None:
    scene, _ = episodes()
    with pytest.raises(Exception, match="not a method"):
        FingertipPipeline(scene, capacitive_method="nope").fit()
