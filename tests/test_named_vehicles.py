"""The four named vehicles are vehicle files in the package, read by the loader of a user's
file: their specs, compiled MuJoCo models and the cache keys built on them are the same,
to the bit, as when they were written in Python (the digests below were taken then)."""

import hashlib
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, get_profile
from dgt_lib.core.vehicle_file import load_vehicle
from dgt_lib.core.vehicle_generator import generated_vehicles
from dgt_lib.core.vehicle_range import resolve_vehicle
from dgt_lib.core.vehicles import NAMED_VEHICLE_DIR, VEHICLE_SPECS, get_vehicle, is_named
from dgt_lib.stages.collect import episode_config
from dgt_lib.stages.conditioned import conditioned_config
from dgt_lib.stages.dataset import _dataset_config
from dgt_lib.stages.ground_truth import ground_truth_config, ground_truth_pairs
from dgt_lib.stages.train import model_config
from dgt_lib.world.mujoco_model import build_model
from dgt_lib.world.worlds import from_heightmap

SPEC_HASH = {"jeep": "6682d31637fd7ebc", "vw_van": "ba6516f19fc344b6",
             "mercedes_van": "8aa26b7e886ac5d4", "carla_cola": "b3d10de23eecccf4"}
"""``config_hash`` of each spec: every field, floats by their shortest exact repr."""
MODEL_SHA256 = {"jeep": "03413e2afa01b92a", "vw_van": "7da7ad164b0e802d",
                "mercedes_van": "90a4df39b93faa10", "carla_cola": "63dc8a9896139de3"}
"""SHA-256 (first 16 hex digits) of each vehicle's compiled model on a flat 30 × 30 world,
as ``mj_saveModel`` writes it under :data:`MODEL_MUJOCO`."""
MODEL_MUJOCO = "4.0.0"
EPISODE_KEY = {"jeep": "d2152712e30062c0", "vw_van": "2a3b4a8e48014236",
               "mercedes_van": "ebdc0e8f2355a48e", "carla_cola": "a200b8e3e7babaed"}
GROUND_TRUTH_KEY = {"hill/carla_cola": "9fb243fe45c7218f", "ridge/mercedes_van": "2a8fc821080ba13b",
                    "ridge/jeep": "e7f5b65bfe9fd4b0", "eval/jeep": "823a9166e5370a57",
                    "eval/vw_van": "b8d502ee676f1e29"}
DATASET_KEY = "19647167348b9450"  # of a stand-in BEV map (the key's vehicles are the point)
MODEL_KEY = {"multitask": "146a1c312a7f39d6", "single:jeep": "94b56029582d69d1",
             "single:vw_van": "196d6736b96f3c83", "single:mercedes_van": "600d66b069fd5bb0",
             "single:carla_cola": "f7a56fcb8925e07f"}
CONDITIONED_KEY = {None: "a1899b5597c03fc2", "jeep": "1533b031a1329efc",
                   "vw_van": "9426f22cbc7db3b2", "mercedes_van": "4d502d3e8bc84795",
                   "carla_cola": "a7434e3fdd6d69c3"}
GENERATED_HASH = "b137110d38a342c3"  # generated_vehicles(): mixes of the named four


def test_the_named_vehicles_are_the_package_s_vehicle_files_read_by_the_user_loader():
    assert sorted(p.name for p in NAMED_VEHICLE_DIR.iterdir()) == sorted(
        f"{name}.toml" for name in VEHICLES)
    assert tuple(VEHICLE_SPECS) == VEHICLES
    for name in VEHICLES:
        assert load_vehicle(NAMED_VEHICLE_DIR / f"{name}.toml") == get_vehicle(name)
        assert resolve_vehicle(NAMED_VEHICLE_DIR / f"{name}.toml") == resolve_vehicle(name)
        assert is_named(get_vehicle(name))


@pytest.mark.parametrize("name", VEHICLES)
def test_every_field_of_a_named_vehicle_is_unchanged_to_the_bit(name):
    assert artifacts.config_hash(get_vehicle(name)) == SPEC_HASH[name]


def _model_sha256(name: str) -> str:
    model = build_model(from_heightmap(np.zeros((30, 30)), 0.4), get_vehicle(name))
    buffer = np.empty(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return hashlib.sha256(buffer.tobytes()).hexdigest()[:16]


@pytest.mark.skipif(mujoco.__version__ != MODEL_MUJOCO,
                    reason=f"the digests are of MuJoCo {MODEL_MUJOCO}'s model files")
@pytest.mark.parametrize("name", VEHICLES)
def test_a_named_vehicle_s_compiled_model_is_unchanged_to_the_bit(name):
    assert _model_sha256(name) == MODEL_SHA256[name]


def test_the_cache_keys_built_on_the_named_vehicles_are_unchanged():
    """Stored episodes, ground truth, datasets and models of ``smoke`` stay valid."""
    prof = get_profile("smoke")
    assert {v: artifacts.config_hash(episode_config(prof, v, 0)) for v in VEHICLES} \
        == EPISODE_KEY
    assert {f"{w}/{v}": artifacts.config_hash(ground_truth_config(w, v, prof))
            for w, v in ground_truth_pairs()} == GROUND_TRUTH_KEY
    bev = SimpleNamespace(channels=np.zeros((2, 3, 3), np.float32),
                          observed=np.ones((3, 3), bool))
    assert artifacts.config_hash(_dataset_config(prof, bev)) == DATASET_KEY
    assert {k: artifacts.config_hash(model_config(prof, None, k, dataset_hash="0" * 16))
            for k in MODEL_KEY} == MODEL_KEY
    assert {v: artifacts.config_hash(conditioned_config(prof, None, v, dataset_hash="0" * 16))
            for v in CONDITIONED_KEY} == CONDITIONED_KEY
    assert artifacts.config_hash(generated_vehicles()) == GENERATED_HASH
