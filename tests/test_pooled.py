"""PooledNet (dgt_lib.beyond.pooled): the dense costmap equals running every window on its
own, its inputs are altitude-free, and trained like DGTNet it learns that uphill costs more."""

import numpy as np
import pytest
import torch
from scipy import ndimage

from dgt_lib.beyond import pooled
from dgt_lib.beyond.dense import directional_costmap_dense
from dgt_lib.core.config import TrainConfig
from dgt_lib.core.geometry import GridSpec
from dgt_lib.learning.run import train_network
from dgt_lib.learning.training import TrainingSet
from dgt_lib.perception.dataset import TRAIN, PatchDataset
from dgt_lib.perception.patches import PATCH_COLS, PATCH_ROWS, extract_patches, rotate_map
from tests.test_costmap import synthetic_bev
from tests.test_patches import make_bev


def hilly_bev(shape=(41, 41), seed=0):
    """A smooth random hill map with a hole in its observed mask."""
    rng = np.random.default_rng(seed)
    height = (ndimage.gaussian_filter(rng.normal(size=shape), 3.0) * 15.0).astype(np.float32)
    observed = np.ones(shape, bool)
    observed[3:8, 30:36] = False
    return make_bev(GridSpec((1.0, -2.0), 0.4, shape), height, observed, rng)


def small_net(seed=0, **kwargs) -> pooled.PooledNet:
    """An untrained PooledNet with non-trivial BatchNorm statistics, in eval mode."""
    torch.manual_seed(seed)
    model = pooled.PooledNet(("jeep", "vw_van"), **{"width": 8, "depth": 2, "fc_hidden": 16,
                                                     **kwargs})
    for m in model.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            m.running_mean.uniform_(-0.2, 0.2)
            m.running_var.uniform_(0.5, 2.0)
    return model.eval()


def test_dense_costmap_equals_running_every_window_on_its_own():
    bev, model = hilly_bev((41, 37)), small_net()
    literal = directional_costmap_dense(bev, model, 8, literal=True, progress=False)
    dense = directional_costmap_dense(bev, model, 8, progress=False)
    assert dense.shape == (2, 8, 41, 37)
    assert np.all(dense[:, :, ~bev.observed] == 1.0)
    assert np.abs(dense - literal).max() < 1e-5  # measured 6e-8: float rounding only
    assert np.ptp(dense[:, :, bev.observed]) > 0.01  # not a constant map


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
def test_a_network_on_a_gpu_gives_the_costmap_it_gives_on_the_cpu():
    """train_pooled leaves a PooledNet where it trained it: the map-level methods take numpy
    on the CPU and must run it there (up to TF32 rounding of the convolutions)."""
    bev, model = hilly_bev((41, 37)), small_net(seed=2)
    on_cpu = directional_costmap_dense(bev, model, 8, progress=False)
    literal_cpu = directional_costmap_dense(bev, model, 8, literal=True, progress=False)
    model.to("cuda")
    assert model.device.type == "cuda"
    np.testing.assert_allclose(directional_costmap_dense(bev, model, 8, progress=False),
                               on_cpu, atol=2e-3)
    np.testing.assert_allclose(directional_costmap_dense(bev, model, 8, literal=True,
                                                         progress=False), literal_cpu, atol=2e-3)
    np.testing.assert_allclose(model.empty_window(), model.cpu().empty_window(), atol=2e-3)


def test_tiles_and_the_needed_windows_do_not_change_the_field():
    bev, model = hilly_bev((41, 37)), small_net(seed=1)
    rotated = rotate_map(bev, 0.7)
    whole = model.window_field(rotated.channels, rotated.observed)
    n_a, n_b = whole.shape[1:]
    needed = np.zeros((n_a, n_b), bool)
    needed[10:30, 5:9] = needed[40:44, 30:50] = True
    part = model.window_field(rotated.channels, rotated.observed, needed, tile=7)
    np.testing.assert_allclose(part[:, needed], whole[:, needed], atol=1e-6)
    assert np.all(part[:, ~needed] == 0)


def test_a_window_of_the_padded_rotated_map_is_the_context_crop_at_its_pose():
    bev, m = hilly_bev((41, 37)), 3
    rotated = rotate_map(bev, 0.7)
    x = np.concatenate([rotated.channels, rotated.observed[None].astype(np.float32)])
    x = np.pad(x, ((0, 0), (m, m), (m, m)))
    corner_r, corner_c = rotated.transform.xy_to_rotated(*bev.grid.cell_to_xy(0, 0))
    corner = (int(round(corner_r - 10.5)), int(round(corner_c - 3)))
    for a, b in ((40, 30), corner):  # inside the map, and on its corner (context off the map)
        crop = pooled.context_crops(bev, rotated.transform.window_pose(a, b)[None], m)[0]
        window = x[:, a : a + PATCH_ROWS + 2 * m, b : b + PATCH_COLS + 2 * m]
        seen = crop[-1] > 0.5
        assert np.array_equal(window[-1] > 0.5, seen) and seen.any()
        np.testing.assert_allclose(window[:-1, seen], crop[:-1, seen], atol=1e-5)
    assert not seen.all()  # the corner's context reaches off the map
    pose = rotated.transform.window_pose(40, 30)[None]
    patches, _ = extract_patches(bev, pose)
    np.testing.assert_array_equal(pooled.context_crops(bev, pose, m)[0, :6, m:-m, m:-m],
                                  patches[0])


def test_altitude_does_not_matter_and_slopes_point_forward():
    grid = GridSpec((0.0, 0.0), 0.4, (40, 40))
    x, _ = grid.cell_centers()
    bev = synthetic_bev((0.2 * x).astype(np.float32))  # rises toward +x
    model = small_net()
    poses = np.array([[8.0, 8.0, 0.0], [8.0, 8.0, np.pi]])  # facing uphill, downhill
    crops = torch.from_numpy(pooled.context_crops(bev, poses, model.margin))
    with torch.no_grad():
        prepared = model.prepare(crops)
        high = crops.clone()
        high[:, pooled.HEIGHT] += 500.0  # a plateau 500 m up
        np.testing.assert_allclose(model(high).numpy(), model(crops).numpy(), atol=1e-6)
    forward = prepared[:, len(pooled.SCALARS)] * model.slope_scale  # ∂H̄/∂forward [m/m]
    np.testing.assert_allclose(forward[0].numpy(), 0.2, atol=1e-4)
    np.testing.assert_allclose(forward[1].numpy(), -0.2, atol=1e-4)
    np.testing.assert_allclose(prepared[:, len(pooled.SCALARS) + 1].numpy(), 0.0, atol=1e-4)


def test_trained_like_dgtnet_it_learns_that_uphill_costs_more():
    """Labels from the forward grade only (uphill hard, downhill easy) on a wavy hill:
    train_pooled (DGTNet's loop and recipe), then the dense costmap's uphill layer costs more."""
    grid = GridSpec((0.0, 0.0), 0.4, (60, 60))
    x, y = grid.cell_centers()
    bev = synthetic_bev((0.25 * x + 0.6 * np.sin(y / 3.0)).astype(np.float32))
    rng = np.random.default_rng(0)
    n = 480
    pose = np.stack([rng.uniform(6, 18, n), rng.uniform(6, 18, n), rng.uniform(-np.pi, np.pi, n)],
                    axis=1)
    labels = 1 / (1 + np.exp(-(0.5 - 8.0 * 0.25 * np.cos(pose[:, 2]))))
    model = small_net(depth=2)
    ds = PatchDataset(patches=pooled.context_crops(bev, pose, model.margin),
                      observed=np.ones((n, 1), bool), labels=labels.astype(np.float32),
                      vehicle=np.zeros(n, np.int8), trajectory=np.arange(n, dtype=np.int32),
                      pose=pose.astype(np.float32), split=np.repeat(np.int8([0, 1, 2]), n // 3))
    model.set_normalization(ds.patches, np.flatnonzero(ds.split == TRAIN))
    cfg = TrainConfig(epochs=25, batch_size=32, learning_rate=3e-3, lr_schedule="cosine",
                      selection="last")
    result = pooled.train_pooled(model, ds, cfg, progress=False)
    assert result.metrics["jeep"]["spearman"] > 0.9
    cost = directional_costmap_dense(bev, model, 8, progress=False)[0]
    centre = cost[:, 20:40, 20:40].mean(axis=(1, 2))
    assert np.argmax(centre) == 0  # +x is uphill
    assert centre[4] < centre.min() + 0.02  # −x is downhill: (one of) the cheapest
    assert centre[0] - centre[4] > 0.5  # labels: 0.82 against 0.08


def test_train_network_refuses_a_model_whose_heads_are_not_the_vehicles():
    model = small_net()
    ds = PatchDataset(patches=np.zeros((6, 7, 22 + 2 * model.margin, 7 + 2 * model.margin),
                                       np.float32), observed=np.ones((6, 1), bool),
                      labels=np.full(6, 0.5, np.float32), vehicle=np.zeros(6, np.int8),
                      trajectory=np.arange(6, dtype=np.int32), pose=np.zeros((6, 3), np.float32),
                      split=np.int8([0, 0, 0, 1, 1, 2]))
    cfg = TrainConfig(epochs=1, batch_size=2)
    with pytest.raises(ValueError, match="heads"):
        train_network(model, TrainingSet.select(ds, ("jeep",), cfg), cfg, progress=False)
    with pytest.raises(ValueError, match="crops"):
        model(torch.zeros(2, 6, 22, 7))


def test_the_dense_incremental_costmap_equals_the_dense_costmap_after_every_frame():
    """A map observed frame by frame (tests/test_incremental.py's terrain): after each
    refresh the incremental layers equal a full dense costmap of the same map, and a frame
    re-evaluates fewer windows than the whole map has."""
    from dgt_lib.beyond.incremental import DenseIncrementalCostmap
    from tests.test_incremental import explore, terrain

    heights, model = terrain(), small_net(seed=2)
    observed = np.zeros(heights.shape, bool)
    observed[:30, :26] = True
    bev = synthetic_bev(heights, observed)
    inc = DenseIncrementalCostmap(bev.grid, model, 8)
    full = directional_costmap_dense(bev, model, 8, progress=False)
    inc.refresh(bev)
    assert np.abs(inc.cost - full).max() < 1e-5
    all_windows = 8 * heights.size  # about what a full dense costmap evaluates
    for box in ((slice(24, 36), slice(20, 30)), (slice(40, 50), slice(2, 12))):
        new = synthetic_bev(*explore(bev.mean_height, bev.observed, box))
        stats = inc.refresh(new)
        expected = directional_costmap_dense(new, model, 8, progress=False)
        assert np.abs(inc.cost - expected).max() < 1e-5
        assert np.abs(expected - full).max() > 0.01  # the frame changed costs
        assert 0 < stats.windows < all_windows / 2
        bev, full = new, expected
    assert inc.refresh(bev).windows == 0  # nothing new: nothing evaluated


def test_a_saved_network_comes_back_with_its_size_and_its_predictions():
    model = small_net(seed=3, width=6, depth=3, fc_hidden=12)
    again = pooled.PooledNet.from_state_dict(model.state_dict(), ("jeep", "vw_van"))
    assert (again.width, again.depth, again.fc_hidden, again.margin) == (6, 3, 12, 4)
    bev = hilly_bev((30, 30))
    rotated = rotate_map(bev, 0.3)
    np.testing.assert_array_equal(again.window_field(rotated.channels, rotated.observed),
                                  model.window_field(rotated.channels, rotated.observed))
    nothing = rotate_map(synthetic_bev(np.zeros((30, 30), np.float32),
                                       np.zeros((30, 30), bool)), 0.3)
    field = model.window_field(nothing.channels, nothing.observed)  # nothing observed
    np.testing.assert_allclose(field, np.broadcast_to(model.empty_window()[:, None, None],
                                                      field.shape), atol=1e-6)


def test_the_bfloat16_copy_keeps_its_inputs_in_float32_and_stays_close():
    bev, model = hilly_bev((41, 37)), small_net(seed=4)
    fast = pooled.bfloat16_copy(model)
    assert fast.stem.weight.dtype == torch.bfloat16 and model.stem.weight.dtype == torch.float32
    assert fast.input_mean.dtype == fast.slope_scale.dtype == torch.float32
    exact = directional_costmap_dense(bev, model, 8, progress=False)
    approx = directional_costmap_dense(bev, fast, 8, progress=False)
    assert approx.dtype == np.float32
    diff = np.abs(approx - exact)
    assert 0 < diff.max() < 0.02 and diff.mean() < 0.005  # bfloat16: not exact, close
