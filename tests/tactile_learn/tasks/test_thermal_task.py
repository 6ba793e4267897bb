"""The thermal task: evaluation data and duration views, metrics, classical methods, the oracle,
and the learning hooks (network, loss, ONNX export parity)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from synth.dataset import generate, simulate_shard
from synth.errors import DataError, InputError
from synth.scene import load_scene
from tactile_learn.estimators.base import Estimator
from tactile_learn.estimators.classical.curve_match import detect_onset
from tactile_learn.tasks import get_task
from tactile_learn.tasks.thermal import DURATIONS_S, ThermalTask, class_names, oracle_accuracy_by_duration, view
from tactile_learn.tasks.thermal_data import eval_data_from_arrays

WNS = load_scene("thermal_wns")
TASK = ThermalTask()
KEYS = {"0.25", "0.5", "1.0", "2.0"}


class TruthEstimator(Estimator):
    """Knows the answer for the rows of one EvalData: checks the metric plumbing."""

    task = "thermal"
    name = "truth"

    def __init__(self, scene: object, labels: np.ndarray, k: int) -> None:
        self.scene = scene
        self.labels = labels
        self.k = k
        self.calls: list[int] = []

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        self.calls.append(len(X))
        out = np.zeros((len(X), self.k + 1), np.float32)
        out[np.arange(len(X)), self.labels[: len(X)]] = 1.0
        return out


@pytest.fixture(scope="module")
def wns_data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("wns")
    generate(WNS, 24, 4242, folder / "d", shard_size=16)
    return folder / "d"


def test_registry_contract_and_input_checks() -> None:
    task = get_task("thermal")
    assert isinstance(task, ThermalTask) and task.default_scene == "thermal"
    w = WNS.sensor.window_samples
    assert task.input_shape(WNS) == (w,) and class_names(WNS) == ("oak", "nylon66", "mild_steel", "none")
    x = np.full((3, w), 30.0, np.float32)
    assert task.check_inputs(x, WNS).dtype == np.float32
    with pytest.raises(InputError, match="negative"):  # the scene's ADC reads 0-100 degC
        task.check_inputs(np.full((2, w), -5.0), WNS)
    with pytest.raises(InputError, match="expected shape"):
        task.check_inputs(x[:, :-1], WNS)
    bad = x.copy()
    bad[1, 3] = np.nan
    with pytest.raises(InputError, match="NaN"):
        task.check_inputs(bad, WNS)
    hot = x.copy()
    hot[2, 0] = WNS.sensor.readout.adc_range_c[1]
    with pytest.raises(InputError, match="saturated"):
        task.check_inputs(hot, WNS)
    cold = x.copy()
    cold[0, 0] = WNS.sensor.readout.adc_range_c[0]
    with pytest.raises(InputError, match="saturated"):
        task.check_inputs(cold, WNS)


def test_views_end_at_onset_plus_duration(wns_data: Path) -> None:
    data = TASK.load_eval_data(wns_data)
    p = WNS.sensor.n_pixels
    assert len(data) == 24 * p and data.inputs.shape == (24 * p, WNS.sensor.window_samples)
    fs = WNS.sensor.readout.sampling_hz
    record, onset = data.extra["record"], data.extra["onset_s"]
    release = data.extra["release_s"]
    for d in DURATIONS_S:
        x, valid = view(data, d)
        # a view exists while the contact lasts (these contacts: 2.2 to 3 s)
        assert np.array_equal(valid, onset + d <= release + 1e-9)
        if d > 3.0:
            assert not valid.any()
            continue
        assert valid.all()
        end = np.floor((onset + d) * fs + 1e-9).astype(int)  # index of the window's last sample
        assert np.array_equal(x[:, -1], record[np.arange(len(record)), end])
        assert ((end / fs) <= onset + d + 1e-9).all() and ((end + 1) / fs > onset + d - 1e-9).all()
    assert np.array_equal(data.inputs, view(data, 2.0)[0])


def test_evaluate_reports_every_duration_and_pools_them(wns_data: Path) -> None:
    data = TASK.load_eval_data(wns_data)
    k = len(WNS.sensor.material_list)
    perfect = TASK.evaluate(TruthEstimator(WNS, data.truth["label"], k), data)
    assert perfect["accuracy"] == 1.0 and set(perfect["accuracy_by_duration"]) == KEYS
    assert all(v == 1.0 for v in perfect["family_accuracy_by_duration"].values())
    assert perfect["confusion_pairs"] == []
    wrong = data.truth["label"].copy()
    contact = wrong < k
    wrong[contact] = (wrong[contact] + 1) % k  # every contact pixel gets the next material
    m = TASK.evaluate(TruthEstimator(WNS, wrong, k), data)
    assert m["accuracy"] == 0.0 and m["contact_accuracy_by_duration"]["1.0"] == 1.0
    top = m["confusion_pairs"][0]
    assert top["count"] > 0 and top["effusivity_true"] > 0 and top["true"] != top["predicted"]


@pytest.mark.parametrize(("method", "floor"), [("curve_match", 0.6), ("physics_fit", 0.85)])
def test_classical_methods_beat_chance_on_clean_long_touches(method: str, floor: float) -> None:
    """One pixel per object (pixels on one object are alike) of 20 clean touches, 2 s of contact;
    chance is 1/3."""
    scene = WNS.with_noise(False)
    arrays = simulate_shard(scene, 31, 0, 20)
    data = eval_data_from_arrays(arrays, scene, "test")
    obj = data.extra["touch"] * 2 + data.extra["latent_object"]
    _, first = np.unique(np.where(data.truth["label"] < 3, obj, -1), return_index=True)
    rows = first[data.truth["label"][first] < 3]
    x, _ = view(data.subset(rows), 2.0)
    est = TASK.classical_methods()[method](scene)
    pred = est.predict_proba(x)
    assert pred.shape == (len(x), 4) and np.allclose(pred.sum(axis=1), 1.0, atol=1e-5)
    assert (pred.argmax(axis=1) == data.truth["label"][rows]).mean() >= floor


def test_onset_detection_finds_the_contact_and_ignores_flat_padding() -> None:
    arrays = simulate_shard(WNS, 8, 0, 4)
    data = eval_data_from_arrays(arrays, WNS, "t")
    fs = WNS.sensor.readout.sampling_hz
    contact = data.truth["label"] < 3
    x, _ = view(data, 1.0)
    onset = detect_onset(x, fs, WNS.sensor.readout.adc_step_k)
    start = (np.floor((data.extra["onset_s"] + 1.0) * fs) + 1 - x.shape[1]).astype(int)  # record index of x[:, 0]
    true_k = np.floor(data.extra["onset_s"] * fs) - start
    assert onset.detected[contact].all() and not onset.detected[~contact].any()
    assert np.abs(onset.index[contact] - true_k[contact]).max() <= 3
    # a window padded on the left (its record started late) keeps a sane noise estimate
    padded = np.concatenate([np.repeat(x[:, :1], 40, axis=1), x[:, :-40]], axis=1)
    sigma = detect_onset(padded, fs, WNS.sensor.readout.adc_step_k).sigma
    assert (sigma[contact] > 0.5 * WNS.sensor.readout.noise_k).all()


def test_oracle_helper_and_reference_metrics(wns_data: Path) -> None:
    data = TASK.load_eval_data(wns_data).subset(slice(0, 48))
    out = oracle_accuracy_by_duration(data)
    assert set(out["oracle_accuracy_by_duration"]) == KEYS
    assert all(0.0 <= v <= 1.0 for v in out["oracle_accuracy_by_duration"].values())
    assert TASK.reference_metrics(data).keys() == out.keys()


def test_npz_input_with_names_and_errors(tmp_path: Path) -> None:
    arrays = simulate_shard(WNS, 3, 0, 5)
    names = np.array(class_names(WNS))[np.where(arrays["latent_material"] < 0, 3, arrays["latent_material"])]
    np.savez(tmp_path / "mine.npz", readings=arrays["readings"], material=names, onset_s=arrays["latent_onset_s"])
    data = TASK.load_eval_data(tmp_path / "mine.npz", WNS)
    assert np.array_equal(
        data.truth["label"], np.where(arrays["latent_material"] < 0, 3, arrays["latent_material"]).ravel()
    )
    np.savez(tmp_path / "nolabels.npz", readings=arrays["readings"])
    with pytest.raises(DataError, match="labels"):
        TASK.load_eval_data(tmp_path / "nolabels.npz", WNS)
    np.savez(tmp_path / "alien.npz", readings=arrays["readings"][:, :1], material=np.array(["copper"] * 5))
    with pytest.raises(DataError, match="copper"):
        TASK.load_eval_data(tmp_path / "alien.npz", WNS)


def test_learning_hooks_network_and_onnx_export(tmp_path: Path) -> None:
    torch = pytest.importorskip("torch")
    onnxruntime = pytest.importorskip("onnxruntime")
    arrays = simulate_shard(WNS, 3, 0, 32)
    stats = TASK.fit_stats(arrays, WNS)
    rng = np.random.default_rng(0)
    x, targets = TASK.training_batch(arrays, WNS, rng)
    assert x.shape == (32 * 4, WNS.sensor.window_samples) and x.dtype == np.float32
    assert targets["label"].min() >= 0 and targets["label"].max() <= 3
    torch.manual_seed(0)
    net = TASK.build_net("tiny", WNS, stats)
    xt, yt = torch.from_numpy(x), torch.from_numpy(targets["label"])
    opt = torch.optim.Adam(net.parameters(), lr=3e-3)
    first = None
    for _ in range(25):
        loss = TASK.loss(TASK.train_forward(net, xt), {"label": yt})
        first = loss.item() if first is None else first
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < first
    net.eval()
    probe = TASK.example_inputs(simulate_shard(WNS, 4, 0, 2), WNS)
    with torch.inference_mode():
        prob = net(torch.from_numpy(probe)).numpy()
        shifted = net(torch.from_numpy(probe + 7.5)).numpy()
    assert prob.shape == (len(probe), 4) and np.allclose(prob.sum(axis=1), 1.0, atol=1e-5)
    assert np.allclose(prob, shifted, atol=1e-4)  # absolute temperature carries no weight
    path = tmp_path / "t.onnx"
    from tactile_learn.export import to_onnx

    to_onnx(net.eval(), torch.from_numpy(probe[:2]), path, "readings", "probabilities", {})
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    for batch in (1, 7):
        got = session.run(None, {"readings": probe[:batch]})[0]
        assert np.abs(got - prob[:batch]).max() < 1e-4
