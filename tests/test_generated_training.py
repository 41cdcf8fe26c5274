"""Generated training vehicles of the conditioned network (``conditioned.generated_vehicles``):
off, every cache key is the kit's; on, they are driven by the named vehicles' rules, labelled
by the same code, split by run, and a model trained without a named vehicle learns from
them but never from that vehicle or a near copy of it."""

import json
from dataclasses import replace

import numpy as np
import pytest

from dgt_lib.beyond.conditioned import spec_vector
from dgt_lib.core import artifacts
from dgt_lib.core.cache_keys import jsonable
from dgt_lib.core.config import VEHICLES, get_profile
from dgt_lib.core.overrides import InvalidOverrideError
from dgt_lib.core.vehicles import VEHICLE_SPECS
from dgt_lib.learning.synthetic import synthetic_dataset
from dgt_lib.learning.training import predict
from dgt_lib.perception.bev import bev_grid
from dgt_lib.perception.dataset import TRAIN, VAL, episode_patches
from dgt_lib.perception.episodes import episode_seed, load_episode
from dgt_lib.stages import conditioned, generated
from dgt_lib.stages.collect import bev_config, episode_config
from dgt_lib.stages.conditioned import (
    conditioned_config,
    conditioned_relpath,
    ensure_conditioned_model,
)
from dgt_lib.stages.generated import (
    collect_generated,
    combined_dataset,
    ensure_generated_dataset,
    generated_episode_relpath,
    profile_generated,
    training_generated,
)
from dgt_lib.stages.paths import data_dir
from dgt_lib.stages.train import RGB_WEIGHTS_ENV_VAR, model_config
from dgt_lib.world.terrain import get_world
from tests.test_conditioned_stage import PROFILE, dataset, ramp_world  # noqa: F401 - fixtures
from tests.test_costmap import synthetic_bev

DIGEST = "0123456789abcdef"
pytestmark = pytest.mark.filterwarnings("ignore:.*near-constant")  # 2 epochs learn little


def test_with_no_generated_vehicles_every_cache_key_is_the_kits(tmp_path, monkeypatch):
    """The setting at 0, by default or set, leaves every key as the kit's without it (the
    stored keys of before it existed read as today's: tests/test_named_vehicles.py)."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    monkeypatch.delenv(RGB_WEIGHTS_ENV_VAR, raising=False)

    def keys(p):
        return {"conditioned": [conditioned_config(p, None, v, dataset_hash=DIGEST)
                                for v in (None, *VEHICLES)],
                "multitask": model_config(p, None, dataset_hash=DIGEST),
                "episodes": [episode_config(p, v, i) for v in VEHICLES for i in range(3)],
                "bev": bev_config("training", p)}

    kit = jsonable(keys(get_profile("smoke")))
    assert "generated" not in json.dumps(kit)
    assert jsonable(keys(get_profile("smoke").with_overrides(
        {"conditioned.generated_vehicles": 0}))) == kit
    assert conditioned_relpath("jeep").name == "conditioned_without_jeep.pt"


def test_the_setting_takes_a_count_and_refuses_a_negative_one():
    p = get_profile("smoke").with_overrides({"conditioned.generated_vehicles": "2"})
    assert [s.name for s in profile_generated(p)] == ["gen_00", "gen_01"]
    with pytest.raises(InvalidOverrideError, match="conditioned.generated_vehicles"):
        get_profile("smoke").with_overrides({"conditioned.generated_vehicles": -1})


def test_generated_runs_follow_the_named_rules_and_are_labelled_by_the_same_code(
        tmp_path, monkeypatch):
    """Two generated vehicles, three short runs each (smoke's count), on the training
    world: stored apart, keyed like a named vehicle's run, seeded by the same rule; the
    dataset's labels are :func:`episode_patches`' and each run lies in one split."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    prof = get_profile("smoke").with_overrides({
        "conditioned.generated_vehicles": 2, "collect.episode_duration_s": 8.0, "workers": 1})
    grid = bev_grid(get_world("training", prof).grid.extent)
    x, _ = grid.cell_centers()
    bev = replace(synthetic_bev((0.1 * x).astype(np.float32)), grid=grid)  # a ramp
    monkeypatch.setattr(generated, "ensure_bev", lambda *a, **k: bev)
    ds = ensure_generated_dataset(prof, progress=False)
    episodes = collect_generated(prof, progress=False)  # loaded back: nothing runs again
    specs = profile_generated(prof)
    assert [(e.vehicle, e.index) for e in episodes] == [(s.name, i) for s in specs
                                                        for i in range(3)]
    for k, (ep, (spec, i)) in enumerate(zip(episodes, [(s, i) for s in specs
                                                        for i in range(3)], strict=True)):
        rel = generated_episode_relpath(spec.name, i)
        assert rel.startswith("episodes/generated/")
        assert artifacts.is_fresh(rel, episode_config(prof, spec, i), profile="smoke/seed-0")
        assert ep.seed == episode_seed(prof.seed, spec, i)
        stored = load_episode(data_dir(prof) / rel)
        np.testing.assert_array_equal(stored.pose, ep.pose)
        expected = episode_patches(ep, bev, prof.collect)["labels"]
        np.testing.assert_array_equal(ds.labels[ds.trajectory == k], expected)
        assert np.all(ds.vehicle[ds.trajectory == k] == specs.index(spec))
    for t in np.unique(ds.trajectory):
        assert len(np.unique(ds.split[ds.trajectory == t])) == 1
    for v in range(2):
        assert {TRAIN, VAL} <= set(ds.split[ds.vehicle == v].tolist())
    assert not list((data_dir(prof) / "episodes").glob("*.npz"))  # no named run touched


def test_a_near_copy_of_the_left_out_vehicle_is_not_trained_on(monkeypatch):
    jeep, cola = VEHICLE_SPECS["jeep"], VEHICLE_SPECS["carla_cola"]
    fake = [replace(jeep, name="gen_00", mass_kg=jeep.mass_kg * 1.02),
            replace(cola, name="gen_01", mass_kg=cola.mass_kg * 0.98)]
    monkeypatch.setattr(generated, "profile_generated", lambda prof: fake)
    names = {v: [s.name for s in training_generated(PROFILE, v)] for v in (None, *VEHICLES)}
    assert names[None] == names["vw_van"] == ["gen_00", "gen_01"]
    assert names["jeep"] == ["gen_01"] and names["carla_cola"] == ["gen_00"]


def test_combined_data_holds_the_seen_and_generated_runs_apart():
    named, gen = synthetic_dataset((30, 20, 20, 20), seed=0), synthetic_dataset((20, 20, 0, 10))
    seen = ("jeep", "mercedes_van", "carla_cola")
    data = combined_dataset(named, seen, gen, ["gen_00", "gen_01", "gen_02", "gen_03"],
                            ["gen_01", "gen_03"])
    assert np.bincount(data.vehicle).tolist() == [30, 20, 20, 20, 10]
    assert len(data) == 100 and not set(data.trajectory[:70]) & set(data.trajectory[70:])
    np.testing.assert_array_equal(data.split[70:], gen.split[np.isin(gen.vehicle, [1, 3])])
    np.testing.assert_array_equal(data.labels[:70], named.labels[named.vehicle != 1])


def test_the_model_trained_without_a_vehicle_learns_from_the_generated_ones(
        ramp_world, monkeypatch):  # noqa: F811 - the fixture
    prof = PROFILE.with_overrides({"conditioned.generated_vehicles": 4})
    named = synthetic_dataset((80, 60, 60, 60), seed=0)
    gen = synthetic_dataset((40, 40, 40, 40), seed=1)  # vehicle k = gen_0k
    monkeypatch.setattr(conditioned, "ensure_generated_dataset", lambda p, progress: gen)
    monkeypatch.setattr(conditioned, "generated_digest",
                        lambda p: artifacts.config_hash(gen.to_arrays()))
    model = ensure_conditioned_model(prof, named, "jeep", progress=False).model
    used = [s.name for s in training_generated(prof, "jeep")]
    assert used and model.vehicles == ("vw_van", "mercedes_van", "carla_cola", *used)
    assert set(model.specs[3:]) <= set(profile_generated(prof))
    jeep = spec_vector("jeep")
    assert not any(np.allclose(row, jeep) for row in model.spec_raw.numpy())
    key = conditioned_config(prof, named, "jeep")
    assert key["generated"]["vehicles"] == 4 and "generated" not in conditioned_config(
        PROFILE, named, "jeep")
    assert conditioned_relpath("jeep", 4).name == "conditioned_without_jeep_gen4.pt"
    monkeypatch.setattr("dgt_lib.beyond.conditioned.train_network",
                        lambda *a, **k: pytest.fail("a cached model was trained again"))
    again = ensure_conditioned_model(prof, named, "jeep", progress=False).model
    assert again.specs == model.specs  # the generated specs come back from the checkpoint
    np.testing.assert_array_equal(predict(again, named.patches[:8]),
                                  predict(model, named.patches[:8]))


def test_the_study_says_how_many_generated_vehicles_it_used(tmp_path):
    """``studies/zero_shot.py --generated 8 --stored`` reads the runs with 8 generated
    vehicles (apart from the others), prints how many each network used and, per seed,
    whether the zero-shot map is within 25 % of the own head's."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    sys.path.append(str(root / "studies"))
    from zero_shot_scores import ZERO_SHOT_METHODS

    (tmp_path / "scores").mkdir()
    rows = [{"world": "hill", "vehicle": "carla_cola", "method": m,
             "mae": 0.13 if m == "zero-shot" else 0.1} for m in ZERO_SHOT_METHODS]
    (tmp_path / "scores" / "seed0_without_carla_cola_gen8.json").write_text(json.dumps(
        {"vehicle": "carla_cola", "seed": 0, "nearest": "mercedes_van", "rows": rows,
         "generated": 8, "generated_used": 6, "plans": {}}))
    run = [sys.executable, str(root / "studies" / "zero_shot.py"), "--seed", "0",
           "--vehicles", "carla_cola", "--out", str(tmp_path), "--stored"]
    env = {**os.environ, "PYTHONPATH": str(root), "MPLBACKEND": "Agg"}
    done = subprocess.run(run + ["--generated", "8"], capture_output=True, text=True,
                          cwd=root, timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    assert "Generated training vehicles: 8 (used by the network without each vehicle, " \
           "over seeds: carla_cola 6)" in done.stdout
    assert "| hill | carla_cola | 1.30 |" in done.stdout  # 30 % above its own head's MAE
    assert "| **vehicles within 25 %** |  | 0 of 1 |" in done.stdout  # a row of the table
    assert (tmp_path / "zero_shot_gen8.png").exists()
    without = subprocess.run(run, capture_output=True, text=True, cwd=root, timeout=300,
                             env=env)
    assert without.returncode != 0 and "no stored scores" in without.stderr
