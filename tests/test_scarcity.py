"""Data scarcity (Claim 4): a fraction of one vehicle's training *runs* is kept — whole runs,
nested across fractions, the same for the multi-task and the single-task model — and the
setting leaves every existing model's cache key unchanged."""

import numpy as np
import pytest

from dgt_lib.core.cache_keys import jsonable as key_form
from dgt_lib.core.config import VEHICLES, TrainConfig, get_profile
from dgt_lib.core.constraints import InvalidSettingError
from dgt_lib.learning.scarcity import UNUSED, keep_runs, kept_training_runs, runs_kept
from dgt_lib.learning.synthetic import synthetic_dataset
from dgt_lib.learning.training import TrainingSet
from dgt_lib.perception.dataset import TEST, TRAIN, VAL
from dgt_lib.stages.train import model_config


@pytest.fixture(scope="module")
def dataset():
    return synthetic_dataset((200, 400, 100, 100), seed=3, patches_per_trajectory=10)


def _runs(ds, vehicle, split):
    v = VEHICLES.index(vehicle)
    return set(np.unique(ds.trajectory[(ds.vehicle == v) & (ds.split == split)]).tolist())


def test_whole_runs_are_kept_and_no_run_is_in_two_splits(dataset):
    thin = keep_runs(dataset, "vw_van", 0.3, seed=0)
    before = _runs(dataset, "vw_van", TRAIN)
    kept = _runs(thin, "vw_van", TRAIN)
    assert len(kept) == round(0.3 * len(before)) and kept < before
    for t in np.unique(thin.trajectory):  # a run's patches share one split
        assert len(np.unique(thin.split[thin.trajectory == t])) == 1
    dropped = before - kept
    assert np.all(thin.split[np.isin(thin.trajectory, list(dropped))] == UNUSED)


def test_only_the_vehicles_training_runs_change(dataset):
    thin = keep_runs(dataset, "vw_van", 0.1, seed=1)
    van = dataset.vehicle == VEHICLES.index("vw_van")
    assert np.array_equal(thin.split[~van], dataset.split[~van])  # other vehicles: all data
    for split in (VAL, TEST):  # every fraction is scored on the same held-out runs
        assert _runs(thin, "vw_van", split) == _runs(dataset, "vw_van", split)
    assert thin.patches is dataset.patches  # shared, not copied


def test_fractions_are_nested_and_seeded(dataset):
    kept = {f: set(kept_training_runs(dataset, "carla_cola", f, seed=2).tolist())
            for f in (1.0, 0.3, 0.1)}
    assert kept[0.1] <= kept[0.3] <= kept[1.0]
    other = set(kept_training_runs(dataset, "carla_cola", 0.3, seed=5).tolist())
    assert other != kept[0.3]  # another run seed draws other runs


def test_at_least_one_run_is_kept():
    assert runs_kept(14, 0.03) == 1 and runs_kept(28, 0.1) == 3 and runs_kept(28, 1.0) == 28
    with pytest.raises(ValueError, match="fraction"):
        runs_kept(10, 0.0)


def test_training_reads_only_the_kept_runs(dataset):
    cfg = TrainConfig(epochs=1, scarce_vehicle="vw_van", scarce_fraction=0.3)
    thin = keep_runs(dataset, "vw_van", 0.3, seed=0)
    data = TrainingSet.select(thin, ("vw_van",), cfg)
    assert set(np.unique(thin.trajectory[data.train_index]).tolist()) == _runs(thin, "vw_van",
                                                                               TRAIN)


def test_settings_are_checked():
    with pytest.raises(ValueError, match="scarce_vehicle"):
        TrainConfig(scarce_fraction=0.3)
    with pytest.raises(ValueError, match="train.scarce_vehicle must be one of none, jeep"):
        TrainConfig(scarce_vehicle="tank", scarce_fraction=0.3)
    with pytest.raises(InvalidSettingError):
        get_profile("smoke").with_overrides({"train.scarce_vehicle": "vw_van",
                                             "train.scarce_fraction": 0.0})


def test_cache_keys_unchanged_by_default_and_changed_when_thinned():
    prof = get_profile("smoke")
    assert "scarce_vehicle" not in key_form(prof.train)
    thin = prof.with_overrides({"train.scarce_vehicle": "vw_van", "train.scarce_fraction": 0.1})
    assert key_form(thin.train)["scarce_fraction"] == 0.1
    a = model_config(prof, None, dataset_hash="d")
    b = model_config(thin, None, dataset_hash="d")
    assert a != b and a["train"] == prof.train
