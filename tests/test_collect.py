"""Collection episodes, the mapping survey and the BEV maps of every world (smoke-sized)."""

import math
from dataclasses import replace

import numpy as np
import pytest

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, CollectConfig, get_profile
from dgt_lib.core.executors import SerialExecutor
from dgt_lib.perception.bev import bev_quality
from dgt_lib.perception.episodes import (
    END_REASONS,
    SPAWN_MARGIN_M,
    SPAWN_MAX_SLOPE_DEG,
    episode_seed,
    run_episode,
    spawn_pose,
)
from dgt_lib.perception.locomotion import locomotion_signal
from dgt_lib.stages.collect import (
    collect_episodes,
    ensure_bev,
    episode_relpath,
    stage_bev,
    stage_collect,
)
from dgt_lib.stages.paths import data_dir as seed_dir
from dgt_lib.world.rendering import survey_poses
from dgt_lib.world.terrain import WORLD_NAMES, get_world


def tiny_profile(episodes=(1, 1, 1, 1), duration_s=8.0, workers=1):
    """The smoke profile with fewer, shorter episodes (same worlds, survey and camera)."""
    p = get_profile("smoke")
    return p.with_(workers=workers, collect=replace(p.collect, episodes=episodes,
                                                    episode_duration_s=duration_s))


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    """A private artifact directory for this module."""
    with pytest.MonkeyPatch.context() as mp:
        path = tmp_path_factory.mktemp("collect_data")
        mp.setenv(artifacts.DATA_ENV_VAR, str(path))
        yield path


@pytest.fixture(scope="module")
def bevs(data_dir):
    """The BEV of every world, built once through the cache (training: survey + episodes)."""
    prof = tiny_profile()
    return {name: ensure_bev(name, prof, executor=SerialExecutor(), progress=False)
            for name in WORLD_NAMES}


@pytest.mark.parametrize("name", WORLD_NAMES)
def test_bev_matches_terrain_and_covers_the_world(bevs, name):
    world = get_world(name, "smoke")
    q = bev_quality(bevs[name], world)
    assert q["coverage"] >= 0.95
    assert q["height_median_abs_err_m"] <= 0.1


def test_tree_cells_have_a_high_gradient(bevs):
    world = get_world("training", "smoke")
    bev = bevs["training"]
    assert len(world.trees) > 0
    x, y = bev.grid.cell_centers()
    near_tree = np.zeros(bev.grid.shape, bool)
    for tx, ty, _, th in world.trees:
        crown = max(1.2, 0.3 * th)  # the simulator's crown radius [m]
        d = np.hypot(x - tx, y - ty)
        near_tree |= d < crown + 1.0
        assert bev.gradient[d < crown + 0.8].max() > 2.0, (tx, ty)
    ground = bev.observed & ~near_tree
    assert np.median(bev.gradient[ground]) < 0.5


def test_training_bev_aggregates_episode_frames(data_dir, bevs):
    prof = tiny_profile()
    arrays = artifacts.load(seed_dir(prof) / "bev" / "training.npz")
    assert int(arrays["survey_frames"]) == len(survey_poses(get_world("training", prof),
                                                            prof.collect))
    assert int(arrays["episode_frames"]) > 0
    hill = artifacts.load(seed_dir(prof) / "bev" / "hill.npz")
    assert int(hill["episode_frames"]) == 0


def test_a_cached_bev_loads_without_generating_its_world(bevs, monkeypatch):
    """Checking a cached map's key must not regenerate the world (`paper`'s 750² training
    world: ~0.5 s on every `dgt plan`, which only needs the dataset's key)."""
    import dgt_lib.stages.collect as collect

    def no_world(*_):
        raise AssertionError("a cached BEV map regenerated its world")

    monkeypatch.setattr(collect, "get_world", no_world)
    for name in WORLD_NAMES:
        bev = ensure_bev(name, tiny_profile(), executor=SerialExecutor(), progress=False)
        np.testing.assert_array_equal(bev.channels, bevs[name].channels)


def test_survey_validates_its_configuration():
    world = get_world("ridge", "smoke")
    with pytest.raises(ValueError, match="survey_overlap"):
        survey_poses(world, CollectConfig(survey_overlap=1.0))
    with pytest.raises(ValueError, match="survey_altitude_m"):
        survey_poses(world, CollectConfig(survey_altitude_m=80.0))


def test_spawn_poses_are_free():
    world = get_world("training", "smoke")
    rng = np.random.default_rng(3)
    x0, x1, y0, y1 = world.grid.extent
    for _ in range(50):
        x, y, yaw = spawn_pose(world, "carla_cola", rng)
        assert x0 + SPAWN_MARGIN_M <= x <= x1 - SPAWN_MARGIN_M
        assert y0 + SPAWN_MARGIN_M <= y <= y1 - SPAWN_MARGIN_M
        assert 0 <= yaw < 2 * math.pi
        d = np.hypot(world.trees[:, 0] - x, world.trees[:, 1] - y) - world.trees[:, 2]
        assert d.min() > 3.2  # half the truck's length
        assert world.slope_deg()[world.grid.xy_to_cell(x, y)] <= SPAWN_MAX_SLOPE_DEG


@pytest.mark.parametrize("world_name", ["training", "hill"])  # rendered whole / on tiles
def test_episodes_are_deterministic_in_their_seed(world_name):
    world = get_world(world_name, "smoke")
    cfg = CollectConfig(episode_duration_s=4.0)
    seed = episode_seed(0, "vw_van", 2)
    a = run_episode(world, "vw_van", seed, cfg)
    c = run_episode(world, "vw_van", episode_seed(0, "vw_van", 3), cfg)
    b = run_episode(world, "vw_van", seed, cfg)  # after another episode in this process
    for k, v in a.to_arrays().items():
        np.testing.assert_array_equal(v, b.to_arrays()[k], err_msg=k)
    assert not np.allclose(a.pose[0], c.pose[0])
    assert a.end_reason in END_REASONS
    driven = np.hypot(*np.diff(a.pose[:, :2], axis=0).T).sum()
    assert driven > 5.0
    assert abs(a.n_frames - (1 + driven // cfg.frame_spacing_m)) <= 1  # a frame every 5 m
    assert a.time_s[-1] <= 4.0 + 1e-3
    assert np.all(np.diff(a.time_s) > 0)


def _true_bev(world):
    """A BEV map of ``world`` from its true heights and colours (one point per cell)."""
    from dgt_lib.perception.bev import BEVAccumulator

    x, y = world.grid.cell_centers()
    acc = BEVAccumulator(world.grid)
    acc.add_points(np.column_stack([x.ravel(), y.ravel(), world.heights.ravel()]),
                   world.colors.reshape(-1, 3))
    return acc.result()


def _keep_on_route_b(hill):
    """Steer back onto Route B (straight north–south), in whichever direction it faces."""
    x_route = hill.routes["B"][0, 0]

    def steer(state):
        target = math.pi / 2 if math.sin(state.yaw) >= 0 else -math.pi / 2
        heading_err = (target - state.yaw + math.pi) % (2 * math.pi) - math.pi
        sign = 1.0 if target > 0 else -1.0  # left of a south-going vehicle is east
        return float(np.clip(2.0 * heading_err - sign * 0.5 * (state.position[0] - x_route),
                             -1, 1))
    return steer


def test_a_stalling_truck_gets_low_locomotion():
    """carla_cola driven up Route B of the hill stalls on the 26° section: L drops
    from ~1 on the flat approach to near 0 where it stalls, and the (paper's) run ends."""
    hill = get_world("hill", "smoke")
    x_route = hill.routes["B"][0, 0]
    start = np.array([x_route, 22.0, math.pi / 2])
    paper_run = CollectConfig(episode_duration_s=40.0)
    ep = run_episode(hill, "carla_cola", 0, paper_run, start_pose=start,
                     steer=_keep_on_route_b(hill), render=False)
    assert ep.end_reason in ("immobilized", "timeout")  # stalled (or still rocking at 40 s)
    assert ep.pose[:, 1].max() < hill.landmarks["B_steep_top"][1]
    at = np.arange(3.0, ep.time_s[-1], 0.5)
    labels = locomotion_signal(ep.time_s, ep.pose[:, :2], at_s=at)
    y = np.interp(at, ep.time_s, ep.pose[:, 1])
    flat = y < hill.landmarks["B_steep_bottom"][1] - 8.0
    assert flat[0] and labels[flat].min() > 0.8
    assert labels[~flat].min() < 0.1
    assert labels[-1] < 0.1  # where it ends, stuck


def test_collection_resumes_after_an_interruption(data_dir):
    prof = tiny_profile(episodes=(2, 1, 0, 0), duration_s=3.0)
    seen = []

    def stop_after_one(ep):
        seen.append((ep.vehicle, ep.index))
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        collect_episodes(prof, executor=SerialExecutor(), progress=False,
                         on_episode=stop_after_one)
    assert seen == [("jeep", 0)]
    first = seed_dir(prof) / episode_relpath("jeep", 0)
    assert first.exists() and not (first.parent / "jeep_0001.npz").exists()
    mtime = first.stat().st_mtime_ns

    computed = []
    episodes = collect_episodes(prof, executor=SerialExecutor(), progress=False,
                                on_episode=lambda ep: computed.append((ep.vehicle, ep.index)))
    assert computed == [("jeep", 1), ("vw_van", 0)]
    assert first.stat().st_mtime_ns == mtime  # loaded, not rerun
    assert [(e.vehicle, e.index) for e in episodes] == [("jeep", 0), ("jeep", 1), ("vw_van", 0)]
    again = []
    collect_episodes(prof, executor=SerialExecutor(), progress=False, on_episode=again.append)
    assert again == []


def test_process_pool_gives_the_same_episodes(data_dir, tmp_path, monkeypatch):
    """The default executor (a spawned process pool of profile.workers) computes
    exactly what the in-process run computes."""
    monkeypatch.setenv(artifacts.DATA_ENV_VAR, str(tmp_path))
    prof = tiny_profile(episodes=(0, 1, 0, 1), duration_s=3.0, workers=2)
    pooled = collect_episodes(prof, progress=False)
    world = get_world("training", prof)
    for ep in pooled:
        ref = run_episode(world, ep.vehicle, episode_seed(prof.seed, ep.vehicle, ep.index),
                          prof.collect, index=ep.index)
        np.testing.assert_array_equal(ep.pose, ref.pose)
        assert ep.end_reason == ref.end_reason


def test_stages_report_what_they_built(data_dir, bevs):
    prof = tiny_profile()
    out = stage_collect(prof)
    assert all(v in out.summary for v in VEHICLES)
    assert out.paths[0].is_dir()
    out = stage_bev(prof)
    assert len(out.paths) == len(WORLD_NAMES) and all(p.exists() for p in out.paths)
    assert "hill" in out.summary and "observed" in out.summary


def test_depth_is_drawn_without_multisampling_where_the_driver_would_change_it():
    """A multisampled depth buffer is resolved differently by each OpenGL driver (NVIDIA's
    by centimetres to metres from Mesa's): depth gets a context without multisampling,
    whole-world and tiled frames alike, except on a renderer whose multisampled depth is
    the same bit for bit (llvmpipe) — checked here on whichever renderer runs the tests."""
    from dgt_lib.world.rendering import TerrainRenderer, onboard_camera_pose, simulator
    from dgt_lib.world.simulator import (
        EXACT_DEPTH_RESOLVE,
        FrameRenderers,
        Simulator,
        opengl_renderer,
    )

    world = get_world("training", "smoke")
    sim = simulator(world, "jeep")
    samples = sim.model.vis.quality.offsamples
    assert samples > 0  # the colour image is antialiased
    x, y, yaw = spawn_pose(world, "jeep", np.random.default_rng(1))
    sim.reset(x, y, yaw)
    pose = onboard_camera_pose(sim)
    tiles = TerrainRenderer(world, max_depth_m=8.0)
    tiles.render(pose)
    sim.render_rgbd(pose, show_vehicle=False)
    exact = any(name in opengl_renderer(tiles._renderers.rgb) for name in EXACT_DEPTH_RESOLVE)
    for renderers in (tiles._renderers, *sim._renderers.values()):
        assert renderers.rgb._mjr_context.offSamples == samples
        assert (renderers.depth is renderers.rgb) == exact
        assert renderers.depth._mjr_context.offSamples == (samples if exact else 0)
    assert sim.model.vis.quality.offsamples == samples
    if exact:  # the premise of sharing: multisampled depth is the depth drawn without
        depths = []
        for separate in (False, True):
            fresh = Simulator(world, "jeep")
            fresh.share_renderers(FrameRenderers.create(fresh.model, fresh.camera.height,
                                                        fresh.camera.width, separate))
            depths.append(fresh.render_rgbd(pose, show_vehicle=False).depth)
            fresh.close()
        assert np.array_equal(depths[0], depths[1], equal_nan=True)


def test_tiled_rendering_equals_the_whole_world_up_to_max_depth():
    """Frames rendered on a tile around the camera equal the whole world's frames
    up to the renderer's max depth, whichever tiles were loaded before."""
    from dgt_lib.world.rendering import TerrainRenderer, onboard_camera_pose, simulator

    world = get_world("training", "smoke")
    max_depth = 8.0
    tiles = TerrainRenderer(world, max_depth_m=max_depth)
    assert tiles.tile_shape[0] < world.grid.height  # really tiled
    sim = simulator(world, "jeep")
    rng = np.random.default_rng(0)
    poses = []
    for _ in range(3):
        x, y, yaw = spawn_pose(world, "jeep", rng)
        sim.reset(x, y, yaw)
        poses.append(onboard_camera_pose(sim))
    first = []
    keys = set()
    for pose in poses:
        first.append(tiles.render(pose))
        keys.add(tiles._current)
    assert len(keys) > 1
    for pose, before in zip(poses[::-1], first[::-1], strict=True):  # revisit cached tiles
        frame = tiles.render(pose)
        whole_depth = sim.render_rgbd(pose, show_vehicle=False).depth
        near = whole_depth <= max_depth
        assert near.sum() > 1000
        np.testing.assert_allclose(frame.depth[near], before.depth[near], atol=0.01)
        np.testing.assert_allclose(frame.depth[near], whole_depth[near], atol=0.01)
