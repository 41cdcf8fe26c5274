"""The costmaps stage's cache: a stored costmap is rebuilt when what it depends on
changes (the model's weights, the slope fit, the inference settings), and only then."""

from dataclasses import replace

import numpy as np
import pytest

from dgt_lib.core import artifacts
from dgt_lib.core.config import TrainConfig, get_profile
from dgt_lib.learning.synthetic import synthetic_dataset
from dgt_lib.stages import costmaps
from dgt_lib.stages.costmaps import ensure_world_costmaps
from dgt_lib.stages.dataset import dataset_fingerprint
from dgt_lib.stages.experiments import experiment_config
from dgt_lib.stages.paths import cache_dir, data_dir
from dgt_lib.stages.train import model_relpath
from tests.test_costmap import ramp, synthetic_bev

TINY = TrainConfig(epochs=2, batch_size=64, learning_rate=2e-3, width=8, fc_hidden=32)
PROFILE = get_profile("smoke").with_(train=TINY)
PROFILE = PROFILE.with_(costmap=replace(PROFILE.costmap, slope_trials=8))
BEV_PATH = "bev/custom/ramp.npz"
pytestmark = pytest.mark.filterwarnings("ignore:.*near-constant")  # 2 epochs learn little


@pytest.fixture(scope="module")
def dataset():
    return synthetic_dataset((120, 60, 60, 40), seed=0)


class BuildLog(list):
    """What ensure_world_costmaps built, in order, and how often it loaded the dataset."""

    dataset_loads = 0


@pytest.fixture
def built(tmp_path, monkeypatch, dataset):
    """ensure_world_costmaps on a small synthetic world and dataset, on the CPU; returns
    the list of costmaps built (the method of each, in order)."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    bev = synthetic_bev(ramp((40, 30)))

    def world_bev(world, prof, progress=True):
        artifacts.ensure(BEV_PATH, {"ramp": 1}, bev.to_arrays, profile=cache_dir(prof))
        return bev, BEV_PATH

    monkeypatch.setattr(costmaps, "world_bev", world_bev)
    log = BuildLog()

    def ensure_dataset(prof, progress=True):
        log.dataset_loads += 1
        return dataset

    monkeypatch.setattr(costmaps, "ensure_dataset", ensure_dataset)
    monkeypatch.setattr(costmaps, "dataset_digest",  # from the cache's metadata: no loading
                        lambda prof, progress=True: dataset_fingerprint(dataset))
    monkeypatch.setattr(costmaps, "ensure_tau_s", lambda prof: 0.6)
    real_load = costmaps.ensure_model
    monkeypatch.setattr(costmaps, "ensure_model",  # on the CPU, also where CUDA is
                        lambda prof, *a, **k: log.append("load model") or real_load(
                            prof.with_(execution=replace(prof.execution, device="cpu")), *a, **k))
    real_network, real_slope = costmaps.directional_costmap, costmaps.slope_costmap
    monkeypatch.setattr(costmaps, "directional_costmap",
                        lambda *a, **k: log.append("network") or real_network(*a, **k))
    monkeypatch.setattr(costmaps, "slope_costmap",
                        lambda *a, **k: log.append("slope") or real_slope(*a, **k))
    return log


def _maps(prof):
    return ensure_world_costmaps("ramp", ("jeep",), prof, methods=("dgt", "slope"),
                                 progress=False)


def test_a_model_retrained_to_the_same_weights_invalidates_no_costmap(built):
    first = _maps(PROFILE)
    assert built == ["load model", "network", "slope"]
    model = data_dir(PROFILE) / model_relpath("multitask")
    sha, experiment = artifacts._file_digest(model), experiment_config("experiment1", PROFILE)
    model.unlink()  # retrained: same data and seed, same weights; other timings in the file
    again = _maps(PROFILE)
    assert artifacts._file_digest(model) != sha  # the checkpoint file did change
    assert built == ["load model", "network", "slope"]  # the costmap built on it did not
    assert experiment_config("experiment1", PROFILE) == experiment  # nor the experiments
    np.testing.assert_array_equal(again.costmap("dgt", "jeep"), first.costmap("dgt", "jeep"))
    _maps(PROFILE.with_(train=replace(TINY, learning_rate=1e-3)))  # other weights
    assert built == ["load model", "network", "slope", "load model", "network"]


def test_a_cached_costmap_is_served_without_loading_its_model(built):
    """`dgt plan` on cached maps checks the model's key, not its weights: no checkpoint
    is loaded (and torch is not imported) unless a costmap must be built, nor the dataset
    (60,000 patches in `paper`) unless a model is trained or the slope fit."""
    _maps(PROFILE)
    assert built == ["load model", "network", "slope"]
    loads = built.dataset_loads  # to train and to fit
    assert loads >= 1
    maps = _maps(PROFILE)
    assert built == ["load model", "network", "slope"]
    assert built.dataset_loads == loads  # its fingerprint keys them, not its patches
    assert maps.costmap("dgt", "jeep").shape[0] == PROFILE.costmap.n_headings


def test_importing_the_plan_command_does_not_import_torch():
    """torch takes ~1 s to import; `dgt plan` on cached maps never needs it."""
    import subprocess
    import sys

    code = ("import sys, dgt_lib.app.cli, dgt_lib.app.plan_one; "
            "print(sorted(m for m in ('torch', 'dgt_lib.learning.model') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


def test_more_slope_trials_rebuild_the_slope_map_not_the_networks(built):
    _maps(PROFILE)
    more = PROFILE.with_(costmap=replace(PROFILE.costmap, slope_trials=9))
    _maps(more)
    assert built == ["load model", "network", "slope", "slope"]
    fits = data_dir(PROFILE) / "baselines" / "slope_models.json.meta.json"
    assert '"trials": 9' in fits.read_text()
    _maps(more.with_(costmap=replace(more.costmap, batch_size=64)))  # same maps, other chunks
    assert built == ["load model", "network", "slope", "slope"]
    _maps(more.with_(costmap=replace(more.costmap, stride=(2, 1))))  # other windows
    assert built == ["load model", "network", "slope", "slope", "load model", "network",
                     "slope"]
