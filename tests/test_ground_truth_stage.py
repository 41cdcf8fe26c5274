"""The ground-truth stage's cache: measured once per profile (every seed shares it),
resumed drive by drive after an interruption, rebuilt when the drive's settings change;
and the scores of a seed's costmaps against it."""

from dataclasses import replace

import numpy as np
import pytest

from dgt_lib.core import artifacts
from dgt_lib.core.config import get_profile
from dgt_lib.core.executors import SerialExecutor
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.evaluation.ground_truth import STATUSES, GroundTruth
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.perception.bev import BEVMap
from dgt_lib.stages import ground_truth as stage
from dgt_lib.world.worlds import from_heightmap

PROFILE = get_profile("smoke")
PROFILE = PROFILE.with_(ground_truth=replace(PROFILE.ground_truth, cells=2))
N_DRIVES = 2 * PROFILE.costmap.n_headings
FLAT = from_heightmap(np.zeros((120, 120), np.float32), 0.4, name="flat")


@pytest.fixture
def drives(tmp_path, monkeypatch):
    """A flat world and a fake drive (L* = 1 − θ/10) that counts its calls; ``stop_after``
    makes the n-th call raise KeyboardInterrupt (Ctrl-C)."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    monkeypatch.setattr(stage, "get_world", lambda name, prof: FLAT)
    calls = {"n": 0, "stop_after": None}

    def fake(profile, world, vehicle, x, y, theta):
        calls["n"] += 1
        if calls["n"] == calls["stop_after"]:
            raise KeyboardInterrupt
        return {"status": 0, "locomotion": 1.0 - theta / 10, "speed_mps": 5.0,
                "cross_track_m": 0.0, "stop_along_m": float("nan"), "sim_s": 4.0}

    monkeypatch.setattr(stage, "drive_job", fake)
    return calls


def _measure(prof=PROFILE):
    return stage.ensure_ground_truth("flat", "jeep", prof, executor=SerialExecutor(),
                                     progress=False)


def test_ground_truth_is_measured_once_per_profile_not_per_seed(drives, tmp_path):
    first = _measure()
    assert drives["n"] == N_DRIVES and first.measured.all()
    assert (tmp_path / "smoke" / "ground_truth" / "flat_jeep.npz").exists()
    again = _measure(PROFILE.with_(seed=1))  # another run seed: the same physics
    assert drives["n"] == N_DRIVES
    np.testing.assert_array_equal(again.locomotion, first.locomotion)
    np.testing.assert_allclose(first.locomotion[0], 1.0 - first.headings / 10)
    assert not list(tmp_path.glob("smoke/seed-*"))  # nothing under a seed
    longer = PROFILE.with_(ground_truth=replace(PROFILE.ground_truth, run_up_m=20.0))
    _measure(longer)  # another drive: measured again
    assert drives["n"] == 2 * N_DRIVES


def test_a_robots_own_spec_is_measured_and_stored_under_its_name(drives, tmp_path,
                                                                 monkeypatch):
    """A vehicle file's spec (not a named vehicle) reaches the drives as the spec itself and
    its ground truth is stored under its name, apart from the named vehicles'."""
    seen = []
    fake = stage.drive_job

    def spy(profile, world, vehicle, x, y, theta):
        seen.append(vehicle)
        return fake(profile, world, vehicle, x, y, theta)

    monkeypatch.setattr(stage, "drive_job", spy)
    robot = replace(get_vehicle("jeep"), name="my_robot", mass_kg=2500.0)
    gt = stage.ensure_ground_truth("flat", robot, PROFILE, executor=SerialExecutor(),
                                   progress=False)
    assert seen and all(v == robot for v in seen)
    assert gt.vehicle == "my_robot" and gt.measured.all()
    assert (tmp_path / "smoke" / "ground_truth" / "flat_my_robot.npz").exists()
    assert not (tmp_path / "smoke" / "ground_truth" / "flat_jeep.npz").exists()


def test_an_interrupted_measurement_resumes_with_only_the_missing_drives(drives, tmp_path):
    drives["stop_after"] = 6
    with pytest.raises(KeyboardInterrupt):
        _measure()
    assert not (tmp_path / "smoke" / "ground_truth" / "flat_jeep.npz").exists()
    assert len(list((tmp_path / "smoke" / "ground_truth").glob("flat_jeep.*.journal"))) == 1
    drives.update(n=0, stop_after=None)
    gt = _measure()
    assert drives["n"] == N_DRIVES - 5  # the 5 journaled drives are not driven again
    assert gt.measured.all() and gt.locomotion.shape == (2, PROFILE.costmap.n_headings)
    assert not list((tmp_path / "smoke" / "ground_truth").glob("*.journal"))


def test_a_seeds_costmaps_are_scored_on_free_cells_for_every_method(monkeypatch):
    grid = FLAT.grid
    k = PROFILE.costmap.n_headings
    cells = np.array([[10.2, 10.2], [20.2, 20.2], [30.2, 30.2]])
    status = np.zeros((3, k), np.int8)
    status[2, :] = STATUSES.index("blocked_terrain")
    truth = np.tile(np.linspace(0.0, 0.7, k), (3, 1))
    gt = GroundTruth("flat", "jeep", cells, np.zeros(3, np.int64), np.zeros(k), 1.0 - truth,
                     status, np.full((3, k), 5.0), np.zeros((3, k)))
    occupancy = np.zeros(grid.shape, np.uint8)
    occupancy[grid.xy_to_cell(20.2, 20.2)] = 1  # cell 1 is occupied: the planner never asks
    bev = BEVMap(grid, np.zeros((6, *grid.shape), np.float32), np.ones(grid.shape, bool),
                 np.ones(grid.shape, np.int64))
    exact = np.broadcast_to(np.linspace(0.0, 0.7, k)[:, None, None], (k, *grid.shape))
    maps = WorldMaps("flat", bev, occupancy, 0.6, {("dgt", "jeep"): exact.astype(np.float32),
                                                    ("binary", "jeep"): np.zeros((1, *grid.shape))})
    monkeypatch.setattr(stage, "ensure_world_costmaps", lambda *a, **kw: maps)
    rows, samples = stage.score_world("flat", {("flat", "jeep"): gt}, PROFILE,
                                      methods=("dgt", "binary"), progress=False)
    dgt, binary = rows
    cost, true = samples[("flat", "jeep", "dgt")]
    assert len(cost) == len(true) == k and np.allclose(cost, true)
    assert dgt["n"] == binary["n"] == k and dgt["excluded"] == k  # cell 0 only
    assert dgt["mae"] == pytest.approx(0.0, abs=1e-6) and dgt["spearman"] == pytest.approx(1.0)
    assert binary["mae"] == pytest.approx(truth[0].mean())
