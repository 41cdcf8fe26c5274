"""The vehicle-conditioned network through the cache: a model trained without one vehicle
is stored, keyed and loaded back to the same predictions; its costmap for any spec comes
from the kit's costmap inference."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from dgt_lib.beyond.conditioned import ConditionedNet, load_conditioned
from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, TrainConfig, get_profile
from dgt_lib.core.vehicle_file import load_vehicle
from dgt_lib.learning.checkpoints import TrainResult, checkpoint_dict, load_checkpoint
from dgt_lib.learning.model import ArchitectureMismatchError
from dgt_lib.learning.synthetic import synthetic_dataset
from dgt_lib.learning.training import predict
from dgt_lib.stages import conditioned, costmaps
from dgt_lib.stages.conditioned import (
    conditioned_config,
    conditioned_relpath,
    ensure_conditioned_costmaps,
    ensure_conditioned_model,
)
from dgt_lib.stages.dataset import dataset_fingerprint
from dgt_lib.stages.paths import cache_dir, data_dir
from dgt_lib.stages.train import model_config
from tests.test_conditioned import TINY
from tests.test_costmap import ramp, synthetic_bev

TRAIN = TrainConfig(epochs=2, batch_size=64, learning_rate=2e-3, width=4, fc_hidden=8)
PROFILE = get_profile("smoke").with_(train=TRAIN)
PROFILE = PROFILE.with_(execution=replace(PROFILE.execution, device="cpu"))
BEV_PATH = "bev/custom/ramp.npz"
TRUCK = Path(__file__).resolve().parents[1] / "examples" / "my_truck.toml"
pytestmark = pytest.mark.filterwarnings("ignore:.*near-constant")  # 2 epochs learn little


@pytest.fixture(scope="module")
def dataset():
    return synthetic_dataset((80, 60, 60, 60), seed=0)


@pytest.fixture
def ramp_world(tmp_path, monkeypatch, dataset):
    """A synthetic ramp world ("ramp") and dataset in a fresh data directory: the stages
    read them instead of collecting."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    bev = synthetic_bev(ramp((50, 40)))

    def world_bev(world, prof, progress=True):
        artifacts.ensure(BEV_PATH, {"ramp": 1}, bev.to_arrays, profile=cache_dir(prof))
        return bev, BEV_PATH

    for module in (costmaps, conditioned):
        monkeypatch.setattr(module, "world_bev", world_bev)
        monkeypatch.setattr(module, "ensure_dataset", lambda prof, progress=True: dataset)
        monkeypatch.setattr(module, "dataset_digest",
                            lambda prof, progress=True: dataset_fingerprint(dataset))
    monkeypatch.setattr(costmaps, "ensure_tau_s", lambda prof: 0.6)
    return bev


def test_a_conditioned_checkpoint_loads_back_to_the_same_predictions_and_not_as_a_dgtnet():
    torch.manual_seed(0)
    net = ConditionedNet(VEHICLES[:3], **TINY).eval()
    net.init_heads([0.9, 0.5, 0.2])
    ckpt = checkpoint_dict(TrainResult(model=net, history=[], best_epoch=0, metrics={}))
    loaded = load_conditioned(ckpt, vehicles=VEHICLES[:3]).model
    x = torch.from_numpy(synthetic_dataset((3, 3, 3, 3)).patches.astype(np.float32))
    with torch.no_grad():
        assert torch.equal(loaded(x), net(x))
        truck = load_vehicle(TRUCK)
        assert torch.equal(loaded.for_vehicles([truck, "carla_cola"])(x),
                           net.heads_for(net.embed(x), [truck, "carla_cola"]))
    with pytest.raises(ArchitectureMismatchError, match="load_conditioned"):
        load_checkpoint(ckpt)


def test_the_model_trained_without_a_vehicle_is_cached_keyed_and_loaded(ramp_world, dataset,
                                                                         monkeypatch):
    first = ensure_conditioned_model(PROFILE, dataset, "carla_cola", progress=False)
    assert first.model.vehicles == ("jeep", "vw_van", "mercedes_van")
    assert (data_dir(PROFILE) / conditioned_relpath("carla_cola")).name == \
        "conditioned_without_carla_cola.pt"
    monkeypatch.setattr("dgt_lib.beyond.conditioned.train_network",
                        lambda *a, **k: pytest.fail("a cached model was trained again"))
    again = ensure_conditioned_model(PROFILE, dataset, "carla_cola", progress=False)
    patches = dataset.patches[:16]
    np.testing.assert_array_equal(predict(again.model, patches), predict(first.model, patches))
    key = conditioned_config(PROFILE, dataset, "carla_cola")
    assert key["leave_out"] == "carla_cola" and key["vehicles"] == list(VEHICLES[:3])
    assert key["dataset"] == model_config(PROFILE, dataset)["dataset"]
    assert conditioned_config(PROFILE, dataset, None)["vehicles"] == list(VEHICLES)
    with pytest.raises(ValueError, match="unknown vehicle"):
        conditioned_config(PROFILE, dataset, "tractor")


def test_a_costmap_for_a_vehicle_from_a_file_is_the_costmap_inference_of_its_head(ramp_world):
    truck = load_vehicle(TRUCK)
    maps = ensure_conditioned_costmaps("ramp", (truck, "jeep"), PROFILE, progress=False)
    k = PROFILE.costmap.n_headings
    assert set(maps) == {"my_truck", "jeep"}
    assert maps["my_truck"].shape == (k, *ramp_world.grid.shape)
    assert np.all((maps["my_truck"] >= 0) & (maps["my_truck"] <= 1))
    folder = data_dir(PROFILE) / "costmaps" / "ramp"
    assert (folder / "conditioned" / "conditioned_for_my_truck+jeep.npz").exists()
    assert not list(folder.glob("*.npz"))  # the scored methods' folder keys the accuracy
    again = ensure_conditioned_costmaps("ramp", (truck, "jeep"), PROFILE, progress=False)
    np.testing.assert_array_equal(again["my_truck"], maps["my_truck"])
