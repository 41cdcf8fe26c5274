"""The four named vehicles are vehicle files in the package, read by the loader of a user's
file: their specs, compiled MuJoCo models and the cache keys built on them are the same,
to the bit, as when they were written in Python (the digests below were taken then)."""

import dataclasses
import hashlib
import json
from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

from dgt_lib.core.cache_keys import jsonable
from dgt_lib.core.config import VEHICLES, get_profile
from dgt_lib.core.vehicle_file import load_vehicle
from dgt_lib.core.vehicle_generator import generated_vehicles
from dgt_lib.core.vehicle_range import resolve_vehicle
from dgt_lib.core.vehicles import NAMED_VEHICLE_DIR, VEHICLE_SPECS, get_vehicle, is_named
from dgt_lib.stages.collect import episode_config
from dgt_lib.stages.conditioned import conditioned_config
from dgt_lib.stages.dataset import _dataset_config
from dgt_lib.stages.ground_truth import ground_truth_config
from dgt_lib.stages.train import model_config
from dgt_lib.world.mujoco_model import build_model
from dgt_lib.world.worlds import from_heightmap


def every_field_hash(obj: object) -> str:
    """The hash of ``obj`` with every field of every dataclass (the form keys were stored in
    when the digests below were taken)."""
    def form(o: object) -> object:
        if dataclasses.is_dataclass(o) and not isinstance(o, type):
            return {"__type__": type(o).__name__, **form(dataclasses.asdict(o))}
        if isinstance(o, dict):
            return {str(k): form(v) for k, v in o.items()}
        return [form(v) for v in o] if isinstance(o, (list, tuple)) else o
    text = json.dumps(form(obj), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


SPEC_HASH = {"jeep": "6682d31637fd7ebc", "vw_van": "ba6516f19fc344b6",
             "mercedes_van": "8aa26b7e886ac5d4", "carla_cola": "b3d10de23eecccf4"}
"""Every field of each spec, floats by their shortest exact repr (:func:`every_field_hash`)."""
MODEL_SHA256 = {
    "4.0.0": {"jeep": "03413e2afa01b92a", "vw_van": "7da7ad164b0e802d",
              "mercedes_van": "90a4df39b93faa10", "carla_cola": "63dc8a9896139de3"},
    "4.0.1": {"jeep": "e5df0f501ecad140", "vw_van": "c1933d4072513758",
              "mercedes_van": "466d000bd539b37c", "carla_cola": "06a0ecc85d0bc593"},
}
"""SHA-256 (first 16 hex digits) of each vehicle's compiled model on a flat 30 × 30 world,
as ``mj_saveModel`` writes it, by MuJoCo version (the file differs between versions). The
4.0.0 digests were taken when the vehicles were written in Python; the 4.0.1 ones from the
vehicle files, whose 4.0.0 models match those digests."""
SMOKE_KEYS = Path(__file__).parent / "data" / "smoke_keys.json"
"""Keys of ``smoke``'s artifacts built on the named vehicles, as the kit stored them when
the vehicles were written in Python (read in today's form: settings at their defaults left
out)."""
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
    assert every_field_hash(get_vehicle(name)) == SPEC_HASH[name]


def _model_sha256(name: str) -> str:
    model = build_model(from_heightmap(np.zeros((30, 30)), 0.4), get_vehicle(name))
    buffer = np.empty(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return hashlib.sha256(buffer.tobytes()).hexdigest()[:16]


@pytest.mark.skipif(mujoco.__version__ not in MODEL_SHA256,
                    reason=f"digests of MuJoCo {', '.join(MODEL_SHA256)}'s model files only")
@pytest.mark.parametrize("name", VEHICLES)
def test_a_named_vehicle_s_compiled_model_is_unchanged_to_the_bit(name):
    assert _model_sha256(name) == MODEL_SHA256[mujoco.__version__][name]


def test_the_cache_keys_built_on_the_named_vehicles_are_unchanged():
    """Stored episodes, ground truth, datasets and models of ``smoke`` stay valid: each key
    stored then is the key computed now."""
    prof = get_profile("smoke")
    bev = SimpleNamespace(channels=np.zeros((2, 3, 3), np.float32),
                          observed=np.ones((3, 3), bool))
    now = {
        "episode/jeep": episode_config(prof, "jeep", 0),
        "episode/carla_cola": episode_config(prof, "carla_cola", 0),
        "ground_truth/ridge/mercedes_van": ground_truth_config("ridge", "mercedes_van", prof),
        "dataset": _dataset_config(prof, bev),
        "model/multitask": model_config(prof, None, "multitask", dataset_hash="0" * 16),
        "model/single:vw_van": model_config(prof, None, "single:vw_van", dataset_hash="0" * 16),
        "conditioned/jeep": conditioned_config(prof, None, "jeep", dataset_hash="0" * 16),
    }
    stored = json.loads(SMOKE_KEYS.read_text())
    for name, config in now.items():
        assert jsonable(config) == stored[name], name
    assert every_field_hash(generated_vehicles()) == GENERATED_HASH
