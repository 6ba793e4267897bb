"""synth.stimuli.rasterize in slices: a large batch of contacts is rasterised a slice at a time (its
temporaries bounded by RASTER_SAMPLES_PER_CALL), and the frames it gives are the same, bit for bit,
as one piece gives, for every kind of contact and both sensors that rasterise."""

from __future__ import annotations

import numpy as np
import pytest

import synth.stimuli as stimuli
from synth.dataset import simulate_shard
from synth.scene import Scene, load_scene
from synth.suite import load_suite


def _frames(scene: Scene, n: int) -> dict[str, np.ndarray]:
    return dict(simulate_shard(scene, seed=7, index=0, size=n))


@pytest.mark.parametrize(
    ("scene", "n"),
    [
        (load_scene("strips16_wide"), 60),  # every kind of contact, partly off the array
        (load_suite("strips16_unseen5").family("guitar_strings").scene, 8),  # long edges in an object
        (load_scene("capacitive8"), 20),
    ],
    ids=["strips16_wide", "guitar_strings", "capacitive8"],
)
def test_slices_change_no_bit(monkeypatch: pytest.MonkeyPatch, scene: Scene, n: int) -> None:
    whole = _frames(scene, n)
    monkeypatch.setattr(stimuli, "RASTER_SAMPLES_PER_CALL", 1)  # one contact a call
    sliced = _frames(scene, n)
    assert whole.keys() == sliced.keys()
    for name, array in whole.items():
        assert np.array_equal(array, sliced[name]), name


def test_a_large_batch_is_cut_into_slices_within_the_budget(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(1)
    n, size = 10, 12
    batch = stimuli.ContactBatch(
        x_mm=rng.uniform(5, 10, n),
        y_mm=rng.uniform(5, 10, n),
        force_n=rng.uniform(0.5, 2, n),
        radius_mm=rng.uniform(1, 2, n),
        width_mm=rng.uniform(1, 2, n),
        length_mm=rng.uniform(2, 4, n),
        angle_deg=rng.uniform(0, 180, n),
    )
    whole = stimuli.rasterize("block", batch, 0.625, size, 1.3)
    calls: list[int] = []
    inner = stimuli._rasterize

    def counted(kind: str, contacts: stimuli.ContactBatch, *args: float) -> stimuli.Windows:
        calls.append(len(contacts))
        return inner(kind, contacts, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(stimuli, "_rasterize", counted)
    per_contact = (size * stimuli.SUBSAMPLES["block"]) ** 2
    monkeypatch.setattr(stimuli, "RASTER_SAMPLES_PER_CALL", 3 * per_contact)
    sliced = stimuli.rasterize("block", batch, 0.625, size, 1.3)
    assert calls == [3, 3, 3, 1]
    for part in ("y0", "x0", "values"):
        assert np.array_equal(getattr(whole, part), getattr(sliced, part)), part
