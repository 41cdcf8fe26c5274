"""What the map is built from: noisy localisation of the frames (``BEVConfig.pose_*``),
colours made independent of the geometry (``bev.colour``) and the channels the network
sees (``train.inputs``) — the settings of the input attribution and pose-noise studies."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dgt_lib.core.cache_keys import jsonable as key_form
from dgt_lib.core.camera import CameraIntrinsics, RGBDFrame
from dgt_lib.core.config import get_profile
from dgt_lib.core.geometry import GridSpec
from dgt_lib.perception.bev import GRADIENT, BEVMap
from dgt_lib.perception.colour_shuffle import shuffled_colours
from dgt_lib.perception.pose_noise import PoseNoise, perturbed, pose_noise
from dgt_lib.stages.collect import bev_config, episode_config

INTR = CameraIntrinsics(width=8, height=6, fovy_rad=math.radians(60.0))


def frame(position=(10.0, 20.0, 5.0)) -> RGBDFrame:
    rng = np.random.default_rng(0)
    depth = rng.uniform(2.0, 4.0, (INTR.height, INTR.width)).astype(np.float32)
    rgb = rng.integers(0, 255, (INTR.height, INTR.width, 3), dtype=np.uint8)
    return RGBDFrame(rgb, depth, INTR, np.asarray(position, float), np.eye(3))


def test_true_poses_leave_every_frame_and_every_cache_key_as_it_was():
    f = frame()
    assert PoseNoise().localiser(3)(f) is f
    prof = get_profile("smoke")
    assert "pose_noise" not in key_form(episode_config(prof, "jeep", 0))
    assert "bev_settings" not in key_form(bev_config("hill", prof))
    assert "inputs" not in key_form(prof.train)


def test_noisy_poses_change_the_keys_of_what_they_change_and_only_when_set():
    noisy = get_profile("smoke").with_overrides({"bev.pose_sigma_xy_m": 0.3})
    assert key_form(episode_config(noisy, "jeep", 0))["pose_noise"]["sigma_xy_m"] == 0.3
    assert key_form(bev_config("hill", noisy))["bev_settings"]["pose_sigma_xy_m"] == 0.3
    geometry = get_profile("smoke").with_overrides({"train.inputs": "geometry"})
    assert key_form(geometry.train)["inputs"] == "geometry"


def test_a_perturbed_frame_moves_its_points_by_the_offset_and_turns_them_about_the_camera():
    f = frame()
    pts, _ = f.points_world()
    g = perturbed(f, np.array([0.5, -0.2]), math.radians(10.0))
    moved, _ = g.points_world()
    c, s = math.cos(math.radians(10.0)), math.sin(math.radians(10.0))
    rel = pts - f.position
    expected = rel @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T + f.position
    expected[:, :2] += [0.5, -0.2]
    np.testing.assert_allclose(moved, expected, atol=1e-9)
    np.testing.assert_allclose(moved[:, 2], pts[:, 2], atol=1e-9)  # heights stay


def test_the_noise_is_repeatable_by_seed_and_its_drift_grows_as_the_square_root_of_frames():
    noise = PoseNoise(drift_m=0.05)
    def offsets(seed: int, n: int) -> np.ndarray:
        localise = noise.localiser(seed)
        return np.array([localise(frame()).position[:2] - (10.0, 20.0) for _ in range(n)])
    np.testing.assert_array_equal(offsets(4, 5), offsets(4, 5))
    assert not np.array_equal(offsets(4, 5), offsets(5, 5))
    last = np.array([offsets(s, 100)[-1] for s in range(300)])  # the bias after 100 frames
    assert np.std(last) == pytest.approx(0.05 * math.sqrt(100), rel=0.15)
    white = np.array([PoseNoise(sigma_xy_m=0.3).localiser(s)(frame()).position[:2]
                      for s in range(400)]) - (10.0, 20.0)
    assert np.std(white) == pytest.approx(0.3, rel=0.15)


def test_the_profile_s_degrees_become_radians_and_bad_noise_is_refused():
    prof = get_profile("smoke").with_overrides({"bev.pose_sigma_yaw_deg": 2.0})
    assert pose_noise(prof.bev).sigma_yaw_rad == pytest.approx(math.radians(2.0))
    with pytest.raises(ValueError, match="pose_sigma_xy_m"):
        get_profile("smoke").with_overrides({"bev.pose_sigma_xy_m": -0.1})
    with pytest.raises(ValueError, match="colour"):
        get_profile("smoke").with_overrides({"bev.colour": "sepia"})


def rock_on_steep_map(n: int = 64) -> BEVMap:
    """A map whose colour gives the relief away: red exactly where the gradient is high."""
    rng = np.random.default_rng(1)
    channels = np.zeros((6, n, n), np.float32)
    steep = rng.random((-(-n // 8), -(-n // 8))) < 0.3
    steep = np.kron(steep, np.ones((8, 8), bool))[:n, :n]
    channels[GRADIENT] = np.where(steep, 0.8, 0.05)
    channels[0] = np.where(steep, 0.9, 0.1)  # "rock" red on steep cells
    channels[1] = rng.random((n, n))
    channels[3] = rng.random((n, n))
    grid = GridSpec((0.0, 0.0), 0.4, (n, n))
    return BEVMap(grid, channels, np.ones((n, n), bool), np.ones((n, n), np.int64))


def test_shuffled_colours_keep_their_values_and_the_geometry_but_no_longer_mark_steep_ground():
    bev = rock_on_steep_map()
    out = shuffled_colours(bev, seed=0)
    np.testing.assert_array_equal(out.channels[3:], bev.channels[3:])
    np.testing.assert_array_equal(out.observed, bev.observed)
    np.testing.assert_array_equal(np.sort(out.channels[0], axis=None),
                                  np.sort(bev.channels[0], axis=None))  # 64 = 4 whole tiles
    before = np.corrcoef(bev.channels[0].ravel(), bev.channels[GRADIENT].ravel())[0, 1]
    after = np.corrcoef(out.channels[0].ravel(), out.channels[GRADIENT].ravel())[0, 1]
    assert before > 0.99 and abs(after) < 0.5
    assert np.array_equal(shuffled_colours(bev, 0).channels, out.channels)


def test_a_map_not_a_whole_number_of_tiles_gets_every_cell_coloured_from_another_tile():
    bev = rock_on_steep_map(70)
    out = shuffled_colours(bev, seed=2)
    assert out.channels.shape == bev.channels.shape
    assert not np.array_equal(out.channels[0, -6:], bev.channels[0, -6:])  # the border strip too


@pytest.mark.parametrize("inputs, blind_to", [("geometry", slice(0, 3)), ("rgb", slice(3, 6))])
def test_a_network_that_sees_some_channels_ignores_the_others(inputs, blind_to):
    torch = pytest.importorskip("torch")
    from dgt_lib.learning.model import DGTNet

    torch.manual_seed(0)
    net = DGTNet(width=8, fc_hidden=16, inputs=inputs).eval()
    both = DGTNet(width=8, fc_hidden=16).eval()
    both.load_state_dict(net.state_dict())
    x = torch.rand(4, 6, 22, 7)
    y = x.clone()
    y[:, blind_to] = torch.rand_like(y[:, blind_to])
    with torch.no_grad():
        assert torch.equal(net(x), net(y))
        assert not torch.equal(both(x), both(y))
    assert net.architecture()["inputs"] == inputs and "inputs" not in both.architecture()


def test_a_geometry_only_checkpoint_loads_as_geometry_only():
    torch = pytest.importorskip("torch")
    from dgt_lib.learning.checkpoints import TrainResult, checkpoint_dict, load_checkpoint
    from dgt_lib.learning.model import DGTNet

    net = DGTNet(width=8, fc_hidden=16, inputs="geometry")
    ckpt = checkpoint_dict(TrainResult(model=net, history=[], best_epoch=0, metrics={}))
    loaded = load_checkpoint(ckpt).model
    assert loaded.inputs == "geometry"
    assert torch.equal(loaded.input_seen, net.input_seen)


def test_a_noisy_localisation_moves_the_map_not_the_drive():
    from dgt_lib.core.config import CollectConfig
    from dgt_lib.perception.bev import BEVAccumulator, bev_grid
    from dgt_lib.perception.episodes import run_episode
    from dgt_lib.world.terrain import get_world

    world = get_world("hill", get_profile("smoke"))
    cfg = CollectConfig(episode_duration_s=12.0)
    start = (30.0, 20.0, math.pi / 2)
    true = run_episode(world, "jeep", 5, cfg, start_pose=start)
    noisy = run_episode(world, "jeep", 5, cfg, start_pose=start,
                        localise=PoseNoise(sigma_xy_m=0.5, drift_m=0.1).localiser(5))
    np.testing.assert_array_equal(noisy.pose, true.pose)  # the same drive, to the bit
    np.testing.assert_array_equal(noisy.speed_mps, true.speed_mps)
    grid = bev_grid(world.grid.extent)
    a = BEVAccumulator(grid).add_sparse(true.bev).result()
    b = BEVAccumulator(grid).add_sparse(noisy.bev).result()
    assert true.n_frames == noisy.n_frames > 0
    assert not np.array_equal(a.mean_height, b.mean_height)
