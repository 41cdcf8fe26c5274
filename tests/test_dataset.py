"""The patch–label dataset: patches along the runs, labels, 70/15/15 split by trajectory."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, get_profile
from dgt_lib.core.executors import SerialExecutor
from dgt_lib.perception.dataset import TEST, TRAIN, VAL, patch_times, split_by_trajectory
from dgt_lib.stages.collect import collect_episodes, ensure_bev
from dgt_lib.stages.dataset import (
    DATASET_RELPATH,
    dataset_digest,
    dataset_fingerprint,
    ensure_dataset,
    stage_dataset,
)
from dgt_lib.stages.paths import data_dir
from dgt_lib.world.terrain import get_world


def tiny_profile():
    """The smoke profile with fewer, shorter episodes (same worlds, survey and camera)."""
    p = get_profile("smoke")
    return p.with_(workers=1, collect=replace(p.collect, episodes=(3, 3, 2, 2),
                                              episode_duration_s=8.0))


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(artifacts.DATA_ENV_VAR, str(tmp_path_factory.mktemp("dataset_data")))
        prof = tiny_profile()
        ds = ensure_dataset(prof, executor=SerialExecutor(), progress=False)
        yield prof, ds


def test_dataset_arrays_have_the_documented_shapes(built):
    _, ds = built
    n = len(ds)
    assert n > 0
    assert ds.patches.shape == (n, 6, 22, 7) and ds.patches.dtype == np.float16
    assert ds.observed.shape == (n, 22, 7) and ds.observed.dtype == bool
    assert ds.labels.dtype == np.float32 and ds.pose.shape == (n, 3)
    assert set(np.unique(ds.vehicle)) <= set(range(len(VEHICLES)))


def test_labels_are_locomotion_values(built):
    _, ds = built
    assert np.all((ds.labels >= 0) & (ds.labels <= 1))
    assert ds.labels.max() > 0.9  # someone drove at the commanded speed


def test_no_trajectory_lies_in_two_partitions(built):
    _, ds = built
    for t in np.unique(ds.trajectory):
        assert len(np.unique(ds.split[ds.trajectory == t])) == 1
    assert {TRAIN, VAL, TEST} <= set(np.unique(ds.split).tolist())


def test_trajectory_ids_are_unique_per_run(built):
    prof, ds = built
    episodes = collect_episodes(prof, executor=SerialExecutor(), progress=False)
    for t in np.unique(ds.trajectory):
        assert len(np.unique(ds.vehicle[ds.trajectory == t])) == 1
        assert ds.vehicle[ds.trajectory == t][0] == VEHICLES.index(episodes[t].vehicle)


def test_patches_are_cut_where_the_vehicle_was(built):
    prof, ds = built
    world = get_world("training", prof)
    episodes = collect_episodes(prof, executor=SerialExecutor(), progress=False)
    crown = np.maximum(1.2, 0.3 * world.trees[:, 3])  # the simulator's crown radius [m]
    tree_d = np.hypot(ds.pose[:, :1] - world.trees[:, 0], ds.pose[:, 1:2] - world.trees[:, 1])
    open_ground = (tree_d > crown + 1.0).all(axis=1)  # not under a crown
    checked = np.flatnonzero(ds.observed[:, 10:12, 3].all(axis=1) & open_ground)
    assert len(checked) > 10
    for i in checked:
        ep = episodes[ds.trajectory[i]]
        d = np.hypot(*(ep.pose[:, :2] - ds.pose[i, :2]).T)
        assert d.min() < 0.5  # on the run's path
        centre = ds.patches[i, 3, 10:12, 3].astype(np.float32).mean()  # H̄ at the vehicle
        assert abs(centre - world.height_at(*ds.pose[i, :2])) < 0.5


def test_dataset_is_cached(built):
    prof, ds = built
    bev = ensure_bev("training", prof, progress=False)
    assert (data_dir(prof) / DATASET_RELPATH).exists()
    again = ensure_dataset(prof, executor=SerialExecutor(), progress=False)
    np.testing.assert_array_equal(again.labels, ds.labels)
    assert bev.grid == get_world("training", prof).grid
    out = stage_dataset(prof)
    assert str(len(ds)) in out.summary and all(v in out.summary for v in VEHICLES)


def test_a_cached_datasets_digest_is_read_without_loading_its_patches(built, monkeypatch):
    """What keys the models and the slope fit (``dgt plan`` checks it on every query) comes
    from the metadata: the same as hashing the loaded arrays, and no patch is read."""
    prof, ds = built
    meta_path = data_dir(prof) / (DATASET_RELPATH + ".meta.json")
    assert json.loads(meta_path.read_text())["fingerprint"] == dataset_fingerprint(ds)

    load = artifacts.load

    def load_but_the_dataset(path):
        assert Path(path).name != DATASET_RELPATH, "the dataset's patches were loaded"
        return load(path)

    monkeypatch.setattr(artifacts, "load", load_but_the_dataset)
    assert dataset_digest(prof, progress=False) == dataset_fingerprint(ds)


def test_patch_times_follow_interval_start_and_glitches():
    t = np.arange(0.0, 20.0, 0.04)
    valid = np.ones(len(t), bool)
    at = patch_times(t, valid, 2.0, 3.0, 1.0)
    np.testing.assert_allclose(at, np.arange(3.0, 20.0, 2.0))
    valid[(t > 8.9) & (t < 9.1)] = False  # a glitch at 9 s: windows touching it drop
    at = patch_times(t, valid, 2.0, 3.0, 1.0)
    assert 9.0 not in at and 7.0 in at and 11.0 in at
    assert len(patch_times(t[:50], valid[:50], 2.0, 3.0, 1.0)) == 0  # run shorter than start


def test_paper_patch_interval_matches_the_paper_volume():
    """Paper: 30,000 jeep patches from 400 runs ≈ 75 per full 100 s run."""
    cfg = get_profile("paper").collect
    t = np.arange(0.0, cfg.episode_duration_s + 1e-9, 0.04)
    n = len(patch_times(t, np.ones(len(t), bool), cfg.patch_interval_s, cfg.patch_start_s,
                        1.0))
    assert 70 <= n <= 80
    assert cfg.episodes == (400, 400, 300, 200)


def test_split_by_trajectory_is_70_15_15_per_vehicle():
    traj = np.repeat(np.arange(40), 5)
    vehicle = (traj >= 20).astype(np.int8)
    split = split_by_trajectory(traj, vehicle, seed=1)
    for v in (0, 1):
        runs = [np.unique(split[(vehicle == v) & (traj == t)])[0]
                for t in np.unique(traj[vehicle == v])]
        assert np.bincount(runs, minlength=3).tolist() == [14, 3, 3]


def _straight_run(end_reason):
    from dgt_lib.perception.episodes import Episode

    t = np.arange(0.0, 10.0 + 1e-9, 0.04)
    pose = np.column_stack([5.0 + 5.0 * t, np.full_like(t, 20.0), np.zeros_like(t)])
    return Episode("jeep", 0, 0, t.astype(np.float32), pose.astype(np.float32),
                   np.zeros_like(t, np.float32), np.full_like(t, 5.0, np.float32),
                   np.zeros_like(t, np.float32), np.ones(len(t), bool), end_reason, 0)


def test_episode_patches_pair_patches_with_labels_and_skip_artifact_ends():
    from dgt_lib.core.config import CollectConfig
    from dgt_lib.core.geometry import GridSpec
    from dgt_lib.perception.bev import BEVAccumulator
    from dgt_lib.perception.dataset import ARTIFACT_END_S, episode_patches

    grid = GridSpec((0.0, 0.0), 0.4, (100, 200))
    acc = BEVAccumulator(grid)
    x, y = np.meshgrid(np.arange(0.1, 80, 0.2), np.arange(0.1, 40, 0.2))
    pts = np.column_stack([x.ravel(), y.ravel(), 0.1 * x.ravel()])  # a 0.1 grade along x
    acc.add_points(pts, np.full_like(pts, 0.5))
    bev = acc.result()
    cfg = CollectConfig(patch_interval_s=1.0, patch_start_s=3.0)
    full = episode_patches(_straight_run("timeout"), bev, cfg)
    np.testing.assert_allclose(full["times"], np.arange(3.0, 10.0 + 1e-9, 1.0))
    np.testing.assert_allclose(full["labels"], 1.0, atol=1e-3)  # exactly u: L = 1
    np.testing.assert_allclose(full["pose"][:, 0], 5.0 + 5.0 * full["times"], atol=1e-3)
    centre = full["patches"][:, 3, 10:12, 3].mean(axis=1)  # H̄ under the vehicle
    np.testing.assert_allclose(centre, 0.1 * full["pose"][:, 0], atol=0.05)
    cut = episode_patches(_straight_run("off_map"), bev, cfg)
    assert cut["times"].max() <= 10.0 - ARTIFACT_END_S
    assert len(cut["times"]) < len(full["times"])
