"""Training: masked loss, learning, single-task, repeatability, checkpoints, Ctrl-C, cache."""

import math
from dataclasses import replace

import numpy as np
import pytest
import torch

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, ExecutionConfig, TrainConfig, get_profile
from dgt_lib.learning import run as train_run
from dgt_lib.learning import training as train
from dgt_lib.learning.checkpoints import (
    CheckpointError,
    checkpoint_dict,
    load_checkpoint,
    prediction_digest,
    save_checkpoint,
)
from dgt_lib.learning.model import ArchitectureMismatchError, DGTNet, PatchConv2d, centre_heights
from dgt_lib.learning.run import train_model
from dgt_lib.learning.synthetic import synthetic_dataset
from dgt_lib.learning.training import (
    channel_statistics,
    masked_loss,
    predict,
    regression_metrics,
)
from dgt_lib.perception.dataset import TEST, TRAIN
from dgt_lib.stages import train as train_stage
from dgt_lib.stages.train import ensure_model

TINY = TrainConfig(epochs=2, batch_size=64, learning_rate=2e-3, width=8, fc_hidden=32)
# Tests that compare numbers exactly train on the CPU, also where a GPU is present: cuDNN's
# kernels are not bit-reproducible run to run (the GPU has its own test at the end).
CPU = "cpu"


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path / "data"))
    return tmp_path / "data"


@pytest.fixture(scope="module")
def dataset():
    return synthetic_dataset((300, 120, 120, 40), seed=0)


@pytest.fixture(scope="module")
def trained(dataset):
    """A multi-task model trained long enough to learn the synthetic rule."""
    cfg = TrainConfig(epochs=6, batch_size=32, learning_rate=2e-3, width=8, fc_hidden=32)
    return train_model(dataset, cfg, seed=0, progress=False, device=CPU)


def test_masked_loss_gives_other_heads_exactly_zero_gradient():
    torch.manual_seed(0)
    model = DGTNet(width=8, fc_hidden=32)
    x = torch.randn(6, 6, 22, 7)
    head = torch.tensor([1, 1, 0, 1, 0, 1])  # jeep and vw_van patches only
    loss = masked_loss(model(x), torch.rand(6), head)
    loss.backward()
    for j, h in enumerate(model.vehicle_heads):
        if VEHICLES[j] in ("jeep", "vw_van"):
            assert h.weight.grad.abs().sum() > 0
        else:
            assert torch.count_nonzero(h.weight.grad) == 0
            assert torch.count_nonzero(h.bias.grad) == 0
    assert model.rgb.conv1.weight.grad.abs().sum() > 0  # the shared backbone learns


def test_masked_loss_is_the_squared_error_of_the_own_head():
    pred = torch.tensor([[0.1, 0.9], [0.5, 0.2], [0.3, 0.3]])
    loss = masked_loss(pred, torch.tensor([0.0, 0.0, 1.0]), torch.tensor([1, 0, 1]))
    assert loss.item() == pytest.approx((0.9**2 + 0.5**2 + 0.7**2) / 3)


def test_overfits_a_tiny_batch(dataset):
    torch.manual_seed(0)
    model = DGTNet(width=8, fc_hidden=32)
    idx = np.flatnonzero(dataset.split == TRAIN)[:32]
    model.set_normalization(*channel_statistics(dataset.patches, idx))
    x = torch.from_numpy(dataset.patches[idx].astype(np.float32))
    y = torch.from_numpy(dataset.labels[idx])
    head = torch.from_numpy(dataset.vehicle[idx].astype(np.int64))
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    first = None
    for _ in range(80):
        loss = masked_loss(model(x), y, head)
        first = loss.item() if first is None else first
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 2e-3 < first


def test_multitask_training_learns_vehicle_specific_slope_limits(trained, dataset):
    assert trained.model.vehicles == VEHICLES
    assert [h["epoch"] for h in trained.history] == list(range(1, 7))
    val = [h["val_loss"] for h in trained.history]
    assert trained.best_epoch == 1 + int(np.argmin(val))
    assert val[trained.best_epoch - 1] < 0.5 * val[0]
    assert set(trained.metrics) == set(VEHICLES)
    assert trained.metrics["jeep"]["spearman"] > 0.8
    assert trained.metrics["jeep"]["mse"] < 0.03
    # uphill patches with slope 0.3..0.4: passable for the jeep (limit 0.45), not the vw_van (0.25)
    test = dataset.part("test")
    slope = test.patches[:, 5].astype(np.float32).mean(axis=(1, 2))
    uphill = test.patches[:, 3, 0].astype(np.float32).mean(1) > test.patches[:, 3, -1].mean(1)
    probe = test.patches[(slope > 0.3) & (slope < 0.4) & uphill]
    assert len(probe) >= 5
    pred = predict(trained.model, probe)
    assert pred[:, 0].mean() > pred[:, 1].mean() + 0.2


def test_single_task_model_trains_on_one_vehicle_only(dataset):
    steps = []
    result = train_model(dataset, TINY, vehicles=("vw_van",), progress=False, device=CPU,
                         on_batch_end=lambda epoch, step, loss: steps.append(epoch))
    assert result.model.vehicles == ("vw_van",)
    assert predict(result.model, dataset.patches[:5]).shape == (5, 1)
    assert set(result.metrics) == {"vw_van"}
    n_vw_train = int(np.sum((dataset.vehicle == 1) & (dataset.split == TRAIN)))
    assert steps.count(1) == math.ceil(n_vw_train / TINY.batch_size)
    mean, std = channel_statistics(dataset.patches,
                                   np.flatnonzero((dataset.vehicle == 1) & (dataset.split == 0)))
    np.testing.assert_allclose(result.model.input_mean.numpy(), mean)
    np.testing.assert_allclose(result.model.input_std.numpy(), std)


def test_same_seed_same_model(dataset):
    a = train_model(dataset, TINY, seed=3, progress=False, device=CPU)
    b = train_model(dataset, TINY, seed=3, progress=False, device=CPU)
    assert a.history[-1]["val_loss"] == b.history[-1]["val_loss"]
    np.testing.assert_array_equal(predict(a.model, dataset.patches[:50]),
                                  predict(b.model, dataset.patches[:50]))


def test_checkpoint_round_trip_gives_identical_predictions(trained, dataset, tmp_path):
    path = save_checkpoint(tmp_path / "m.pt", trained)
    loaded = load_checkpoint(path, vehicles=VEHICLES,
                             architecture=trained.model.architecture())
    np.testing.assert_array_equal(predict(loaded.model, dataset.patches),
                                  predict(trained.model, dataset.patches))
    assert loaded.history == trained.history
    assert loaded.best_epoch == trained.best_epoch
    assert loaded.metrics == trained.metrics
    assert loaded.config == trained.config


def test_a_checkpoint_written_with_settings_deleted_since_still_loads(trained):
    """Models trained before a setting nobody changed was deleted (``weight_decay`` at 0)
    are loaded, not refused: hours of ``paper`` training stay usable."""
    ckpt = checkpoint_dict(trained)
    ckpt["train_config"] = {**ckpt["train_config"], "weight_decay": 0.0,
                            "label_weighting": "none"}
    loaded = load_checkpoint(ckpt)
    assert loaded.config == trained.config


def test_prediction_digest_follows_the_weights_not_the_training_record(trained):
    ckpt = checkpoint_dict(trained)
    digest = prediction_digest(ckpt)
    timings = [{**h, "seconds": h["seconds"] + 1.0} for h in ckpt["history"]]
    assert prediction_digest({**ckpt, "history": timings, "metrics": {}}) == digest
    for name in ("input_mean", next(iter(ckpt["state_dict"]))):  # normalisation, a weight
        state = dict(ckpt["state_dict"])
        state[name] = state[name].clone()
        state[name].view(-1)[0] += 1e-3
        assert prediction_digest({**ckpt, "state_dict": state}) != digest


def test_wrong_architecture_or_vehicles_is_a_clear_error(trained, tmp_path):
    path = save_checkpoint(tmp_path / "m.pt", trained)
    with pytest.raises(ArchitectureMismatchError, match="width"):
        load_checkpoint(path, architecture=DGTNet(width=16, fc_hidden=32).architecture())
    with pytest.raises(ArchitectureMismatchError, match="heads for"):
        load_checkpoint(path, vehicles=("vw_van",))
    ckpt = checkpoint_dict(trained)
    ckpt["architecture"]["width"] = 16  # weights of width 8 claimed as width 16
    with pytest.raises(ArchitectureMismatchError, match="do not fit"):
        load_checkpoint(ckpt)
    artifacts.save(tmp_path / "other.pt", {"weights": 1})
    with pytest.raises(CheckpointError, match="not a"):
        load_checkpoint(tmp_path / "other.pt")


def test_ctrl_c_keeps_the_best_checkpoint(dataset, tmp_path):
    def interrupt(epoch, step, loss):
        if epoch == 3 and step == 1:
            raise KeyboardInterrupt

    cfg = TrainConfig(epochs=5, batch_size=64, learning_rate=2e-3, width=8, fc_hidden=32)
    path = tmp_path / "best.pt"
    result = train_model(dataset, cfg, progress=False, checkpoint_path=path, device=CPU,
                         on_batch_end=interrupt)
    assert result.interrupted
    assert len(result.history) == 2
    assert result.best_epoch == 1 + int(np.argmin([h["val_loss"] for h in result.history]))
    assert not result.model.training
    saved = load_checkpoint(path)
    assert saved.interrupted and saved.best_epoch == result.best_epoch
    np.testing.assert_array_equal(predict(saved.model, dataset.patches[:64]),
                                  predict(result.model, dataset.patches[:64]))


RESUMABLE = TrainConfig(epochs=4, batch_size=64, learning_rate=2e-3, width=8, fc_hidden=32,
                        mirror_augment=True, lr_schedule="cosine")


def _same_training(a, b):
    """Two results with bit-identical weights, history (but its timings) and best epoch."""
    assert a.best_epoch == b.best_epoch
    strip = [[{k: v for k, v in h.items() if k != "seconds"} for h in r.history] for r in (a, b)]
    assert strip[0] == strip[1]
    sa, sb = a.model.state_dict(), b.model.state_dict()
    assert sa.keys() == sb.keys()
    for k in sa:
        assert torch.equal(sa[k], sb[k]), k


def test_a_training_stopped_by_ctrl_c_resumes_to_the_weights_of_one_never_stopped(
        dataset, tmp_path, capsys):
    """The batch order, the mirror flips, Adam's moments and the cosine schedule all carry
    on from the snapshot: resuming after epoch 2 ends where the uninterrupted run ends."""
    whole = train_model(dataset, RESUMABLE, seed=3, progress=False, device=CPU)
    snapshot = tmp_path / "multitask.resume.pt"

    def interrupt_in_epoch_3(epoch, step, loss):
        if epoch == 3 and step == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train_model(dataset, RESUMABLE, seed=3, progress=False, device=CPU,
                    keep_best_on_interrupt=False, snapshot_path=snapshot, snapshot_every_s=0,
                    on_batch_end=interrupt_in_epoch_3)
    assert "epochs 1–2 are saved" in capsys.readouterr().out
    epochs_run = []
    resumed = train_model(dataset, RESUMABLE, seed=3, progress=False, device=CPU,
                          snapshot_path=snapshot,
                          on_batch_end=lambda epoch, step, loss: epochs_run.append(epoch))
    assert sorted(set(epochs_run)) == [3, 4]  # epochs 1–2 were not trained again
    assert "resuming after epoch 2" in capsys.readouterr().out
    _same_training(resumed, whole)
    assert resumed.metrics == whole.metrics


def test_a_finished_snapshot_gives_its_model_without_training_again(dataset, tmp_path):
    cfg = replace(RESUMABLE, epochs=8, patience=1, lr_schedule="constant")
    snapshot = tmp_path / "single.resume.pt"
    first = train_model(dataset, cfg, vehicles=("jeep",), seed=0, progress=False,
                        device=CPU, snapshot_path=snapshot, snapshot_every_s=0)
    assert len(first.history) < 8  # early stopping ended it (so resuming must not go on)
    steps = []
    again = train_model(dataset, cfg, vehicles=("jeep",), seed=0, progress=False, device=CPU,
                        snapshot_path=snapshot, on_batch_end=lambda *a: steps.append(a))
    assert steps == []
    _same_training(again, first)


def test_a_snapshot_of_another_training_is_not_resumed(dataset, tmp_path, capsys):
    snapshot = tmp_path / "model.resume.pt"
    train_model(dataset, TINY, seed=0, progress=False, device=CPU, snapshot_path=snapshot)
    assert not snapshot.exists()  # < 60 s of training: no snapshot (the default interval)
    train_model(dataset, TINY, seed=0, progress=False, device=CPU, snapshot_path=snapshot,
                snapshot_every_s=0)
    other = replace(TINY, learning_rate=1e-3)
    fresh = train_model(dataset, other, seed=0, progress=False, device=CPU)
    capsys.readouterr()
    for cfg, seed, key in ((other, 0, None), (TINY, 1, None), (TINY, 0, {"dataset": "b"})):
        result = train_model(dataset, cfg, seed=seed, progress=False, device=CPU,
                             snapshot_path=snapshot, snapshot_key=key)
        assert [h["epoch"] for h in result.history] == [1, 2], (cfg, seed, key)
        assert "of another training; training from the start" in capsys.readouterr().out
    snapshot.write_bytes(b"half a file")
    result = train_model(dataset, other, seed=0, progress=False, device=CPU,
                         snapshot_path=snapshot)
    assert "unreadable" in capsys.readouterr().out
    _same_training(result, fresh)


def test_ctrl_c_before_the_first_epoch_ends_is_reraised(dataset):
    def interrupt(epoch, step, loss):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train_model(dataset, TINY, progress=False, on_batch_end=interrupt)


def test_ensure_model_caches_per_kind(dataset, data_dir, monkeypatch):
    calls = []
    real = train_run.train_model
    monkeypatch.setattr(train_run, "train_model",
                        lambda *a, **k: calls.append(k) or real(*a, **k))
    profile = get_profile("smoke").with_(train=TINY)
    first = ensure_model(profile, dataset, "single:vw_van", progress=False)
    again = ensure_model(profile, dataset, "single:vw_van", progress=False)
    assert len(calls) == 1 and calls[0]["vehicles"] == ("vw_van",)
    assert (data_dir / "smoke" / "seed-0" / "models" / "single_vw_van.pt").exists()
    assert not (data_dir / "smoke" / "seed-0" / "models" / "single_vw_van.partial.pt").exists()
    np.testing.assert_array_equal(predict(first.model, dataset.patches[:20]),
                                  predict(again.model, dataset.patches[:20]))
    assert again.history == first.history
    ensure_model(profile.with_(seed=1), dataset, "single:vw_van", progress=False)
    assert len(calls) == 2  # another seed is another model
    with pytest.raises(ValueError, match="unknown model kind"):
        ensure_model(profile, dataset, "single:truck")


def test_ctrl_c_in_training_stops_the_stage_and_caches_no_half_trained_model(
        dataset, data_dir, monkeypatch):
    """Ctrl-C is not swallowed: the stage stops (no next model, no model cached for the
    interrupted one), the models finished before stay cached, and a rerun trains only
    what is missing — the interrupted model from after its last finished epoch."""
    profile = get_profile("smoke").with_(  # the CPU: a GPU's runs differ even unstopped
        train=TrainConfig(epochs=3, batch_size=64, width=8, fc_hidden=32),
        execution=ExecutionConfig(device=CPU))
    real, trained, stop = train_run.train_model, [], [True]

    def interrupt_in_epoch_2(epoch, step, loss):
        if epoch == 2 and stop[0]:
            raise KeyboardInterrupt

    def train_model(*a, **k):
        trained.append(k["vehicles"])
        return real(*a, **k, on_batch_end=interrupt_in_epoch_2 if k["vehicles"] == ("jeep",)
                    else None)

    monkeypatch.setattr(train_run, "train_model", train_model)
    monkeypatch.setattr(train_stage, "SNAPSHOT_EVERY_S", 0.0)  # these epochs take ~0.1 s
    kinds = ("single:carla_cola", "single:jeep", "single:vw_van")
    with pytest.raises(KeyboardInterrupt):
        train_stage.models_stage(profile, dataset, kinds=kinds, progress=False)
    assert trained == [("carla_cola",), ("jeep",)]  # stopped: vw_van never started
    models = data_dir / "smoke" / "seed-0" / "models"
    assert sorted(p.name for p in models.glob("*.pt")) == ["single_carla_cola.pt",
                                                          "single_jeep.resume.pt"]
    stop[0] = False
    trained.clear()
    out = train_stage.models_stage(profile, dataset, kinds=kinds, progress=False)
    assert trained == [("jeep",), ("vw_van",)]  # carla_cola is reused
    assert all(p.exists() for p in out.paths) and len(out.paths) == 3
    assert not list(models.glob("*.resume.pt"))  # each snapshot gone once its model is cached
    never_stopped = train_model(dataset, profile.train, vehicles=("jeep",), seed=0,
                                progress=False, device=CPU)
    _same_training(load_checkpoint(models / "single_jeep.pt"), never_stopped)


def test_channel_statistics_skip_nan_and_match_numpy():
    rng = np.random.default_rng(0)
    x = rng.normal(3.0, 2.0, (50, 6, 22, 7)).astype(np.float16)
    mean, std = channel_statistics(x, chunk=7)
    ref = centre_heights(x.astype(np.float64))  # the input as DGTNet sees it
    np.testing.assert_allclose(mean, ref.mean(axis=(0, 2, 3)), rtol=1e-5)
    np.testing.assert_allclose(std, ref.std(axis=(0, 2, 3)), rtol=1e-5)
    x[:, 3, :4] = np.nan
    mean_nan, _ = channel_statistics(x)
    centred = centre_heights(x.astype(np.float64))
    np.testing.assert_allclose(mean_nan[3], np.nanmean(centred[:, 3]), atol=1e-9)
    assert np.isnan(centred[:, 3, :4]).all() and np.isfinite(centred[:, 3, 4:]).all()


def test_regression_metrics():
    m = regression_metrics(np.array([0.1, 0.5, 0.9]), np.array([0.0, 0.5, 1.0]))
    assert m["n"] == 3
    assert m["mse"] == pytest.approx(0.02 / 3)
    assert m["mae"] == pytest.approx(0.2 / 3)
    assert m["spearman"] == pytest.approx(1.0)
    assert math.isnan(regression_metrics(np.ones(4), np.arange(4.0))["spearman"])


def test_predict_does_not_depend_on_batch_size(trained, dataset):
    x = dataset.patches[:100]
    a = predict(trained.model, x, batch_size=7)
    b = predict(trained.model, x, batch_size=1024)
    assert a.dtype == np.float32 and a.shape == (100, 4)
    np.testing.assert_allclose(a, b, atol=1e-6)


def test_synthetic_dataset_splits_by_trajectory(dataset):
    for t in np.unique(dataset.trajectory):
        assert len(np.unique(dataset.split[dataset.trajectory == t])) == 1
    assert set(np.unique(dataset.split)) == {TRAIN, 1, TEST}
    assert dataset.patches.dtype == np.float16


def test_models_stage_trains_each_kind_once_and_reports(dataset, data_dir):
    profile = get_profile("smoke").with_(train=TINY)
    out = train_stage.models_stage(profile, dataset, kinds=("multitask", "single:carla_cola"),
                             progress=False)
    assert [p.name for p in out.paths] == ["multitask.pt", "single_carla_cola.pt"]
    assert all(p.exists() for p in out.paths)
    assert "multitask (best epoch" in out.summary and "carla_cola mse" in out.summary
    assert load_checkpoint(out.paths[1]).model.vehicles == ("carla_cola",)
    no_cola_val = dataset.subset(~((dataset.vehicle == 3) & (dataset.split == 1)))
    out = train_stage.models_stage(profile, no_cola_val, kinds=("single:carla_cola",),
                                   progress=False)
    assert out.paths == [] and "single:carla_cola skipped" in out.summary


def test_bad_inputs_are_clear_errors(dataset):
    bad = dataset.subset(np.arange(len(dataset)))
    bad.labels[np.flatnonzero(bad.split == TRAIN)[0]] = np.nan
    with pytest.raises(ValueError, match=r"in \[0, 1\]"):
        train_model(bad, TINY, progress=False)
    no_val = dataset.subset(dataset.split != 1)
    with pytest.raises(ValueError, match="validation"):
        train_model(no_val, TINY, progress=False)
    with pytest.raises(ValueError, match="unknown vehicle"):
        train_model(dataset, TINY, vehicles=("truck",), progress=False)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
def test_a_model_trained_on_a_gpu_predicts_the_same_on_the_cpu(dataset, tmp_path):
    """Up to TF32 rounding: cuDNN convolutions on recent GPUs round inputs to 10 bits."""
    result = train_model(dataset, TINY, seed=0, progress=False, device="cuda")
    assert next(result.model.parameters()).is_cuda
    loaded = load_checkpoint(save_checkpoint(tmp_path / "gpu.pt", result))  # onto the CPU
    assert next(loaded.model.parameters()).device.type == "cpu"
    np.testing.assert_allclose(predict(loaded.model, dataset.patches),
                               predict(result.model, dataset.patches), atol=2e-3)


def test_a_head_that_predicts_a_constant_is_reported_as_collapsed(trained, dataset):
    import copy

    model = copy.deepcopy(trained.model)
    with torch.no_grad():  # a saturated sigmoid: L̂ = 1 for every patch
        model.vehicle_heads[VEHICLES.index("jeep")].bias.fill_(50.0)
    assert train.collapsed_heads(train.evaluate(model, dataset.part("test"))) == ["jeep"]
    assert train.collapsed_heads(trained.metrics) == []  # a model that learned something
    assert train.collapsed_heads({"jeep": {"mse": 0.1}}) == []  # old checkpoints: unknown


def test_the_cosine_schedule_falls_from_the_learning_rate_to_zero():
    cfg = replace(TINY, learning_rate=1e-3, lr_schedule="cosine")
    rates = [train.learning_rate_at(cfg, t, 100) for t in range(101)]
    assert rates[0] == pytest.approx(1e-3) and rates[50] == pytest.approx(5e-4)
    assert rates[100] == pytest.approx(0.0, abs=1e-12)
    assert all(a >= b for a, b in zip(rates[:-1], rates[1:], strict=True))  # never rises
    assert train.learning_rate_at(replace(TINY, learning_rate=1e-3), 99, 100) == 1e-3


def test_selection_last_keeps_the_final_epoch_even_when_an_earlier_one_validated_better(
        dataset):
    cfg = replace(TINY, epochs=4, learning_rate=2e-2, selection="last", patience=1)
    result = train_model(dataset, cfg, progress=False, device=CPU)
    assert len(result.history) == 4 and result.best_epoch == 4  # patience ignored
    best_val = replace(cfg, selection="best_val", patience=None)
    reference = train_model(dataset, best_val, progress=False, device=CPU)
    val = [h["val_loss"] for h in reference.history]
    assert [h["val_loss"] for h in result.history] == val  # the same run, another pick
    assert reference.best_epoch == 1 + int(np.argmin(val))
    if reference.best_epoch != 4:  # the two picks differ: so must the weights
        assert not np.array_equal(predict(result.model, dataset.patches[:32]),
                                  predict(reference.model, dataset.patches[:32]))
    with pytest.raises(ValueError, match="selection"):
        train_model(dataset, replace(TINY, selection="median"), progress=False)
    with pytest.raises(ValueError, match="lr_schedule"):
        train_model(dataset, replace(TINY, lr_schedule="step"), progress=False)


def test_live_taps_train_the_same_network_and_hand_back_full_kernels(dataset):
    losses = {}
    for taps in ("all", "live"):
        steps = losses[taps] = []
        trained = train_model(dataset, replace(TINY, conv_taps=taps), progress=False,
                              device=CPU, on_batch_end=lambda e, s, loss, steps=steps:
                              steps.append(loss))
    # the same initial network on the same batch: the same loss up to float rounding (the
    # runs then drift apart as any two trainings do; the network is checked in test_model)
    assert losses["live"][0] == pytest.approx(losses["all"][0], rel=1e-5)
    assert losses["live"][1] == pytest.approx(losses["all"][1], rel=1e-3)
    # the trained network evaluates with its full kernels, as one loaded from its weights
    assert not any(m.live_taps for m in trained.model.modules() if isinstance(m, PatchConv2d))
    loaded = DGTNet(trained.model.vehicles, width=TINY.width, fc_hidden=TINY.fc_hidden)
    loaded.load_state_dict(trained.model.state_dict())
    np.testing.assert_array_equal(predict(trained.model, dataset.patches[:64]),
                                  predict(loaded, dataset.patches[:64]))
    with pytest.raises(ValueError, match="conv_taps"):
        train_model(dataset, replace(TINY, conv_taps="some"), progress=False)


@pytest.mark.parametrize(("stem", "name", "function"), [
    ("03_multitask_training", "masked_loss", "my_masked_loss"),
    ("04_directional_inference", "heading_bin", "heading_bin")])
def test_the_notebooks_reference_solutions_are_right(stem, name, function):
    import importlib.util
    from pathlib import Path

    from dgt_lib.exercises import RIGHT, grade

    path = Path(__file__).parents[1] / "notebooks" / "solutions" / f"{stem}.py"
    spec = importlib.util.spec_from_file_location(f"solution_{stem[:2]}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert grade(name, getattr(module, function)).status == RIGHT


def test_train_epoch_trains_with_the_loss_it_is_given(dataset):
    """train_epoch's loss_fn is what the gradient comes from: the library's masked loss and
    an equal function give the same weights; a sum instead of the mean gives others."""
    from dgt_lib.learning.training import TrainingSet, masked_loss, train_epoch

    cfg = replace(TINY, epochs=1)
    data = TrainingSet.select(dataset, None, cfg)

    def one_epoch(loss_fn):
        torch.manual_seed(0)
        model = DGTNet(width=cfg.width, fc_hidden=cfg.fc_hidden)
        adam = torch.optim.Adam(model.parameters(), lr=cfg.learning_rate)
        mean = train_epoch(model, adam, data, cfg, np.random.default_rng(0), CPU,
                           loss_fn=loss_fn)
        return mean, torch.cat([p.detach().flatten() for p in model.parameters()])

    lib, same, summed = (one_epoch(f) for f in (
        masked_loss, lambda p, y, h: ((p.gather(1, h[:, None])[:, 0] - y) ** 2).mean(),
        lambda p, y, h: ((p.gather(1, h[:, None])[:, 0] - y) ** 2).sum()))
    assert lib[0] == same[0] and torch.equal(lib[1], same[1])
    assert not torch.equal(lib[1], summed[1])


def test_the_costmap_s_window_predictor_is_predict_in_another_memory_layout(trained, dataset):
    """The costmap runs the network on a channels-last copy (faster CPU convolutions): the
    same locomotion up to float rounding, and the trained model keeps its own layout."""
    model = trained.model
    weight = next(p for p in model.parameters() if p.dim() == 4)  # a 7 × 7 stem kernel
    assert weight.is_contiguous()
    patches = dataset.patches[:300]
    fast = train.window_predictor(model, batch_size=64)(patches)
    np.testing.assert_allclose(fast, train.predict(model, patches, 64), atol=1e-5)
    assert weight.is_contiguous() and not weight.is_contiguous(memory_format=torch.channels_last)
    assert fast.shape == (300, len(model.vehicles)) and np.ptp(fast) > 0.01
