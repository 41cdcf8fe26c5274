"""The C8-equivariant network (dgt_lib.beyond.equivariant): exact 90° equivariance, the
measured 45° error, the heading convention of costmap.py, one pass = per-heading crops."""

import numpy as np
import pytest
import torch
from scipy import ndimage

from dgt_lib.beyond import equivariant as eq
from dgt_lib.beyond import group_conv as gc
from dgt_lib.core.geometry import GridSpec
from dgt_lib.mapping.costmap import directional_costmap_reference
from dgt_lib.perception.dataset import PatchDataset
from dgt_lib.perception.patches import forward_grade
from tests.test_costmap import synthetic_bev
from tests.test_patches import make_bev


def hilly_bev(shape=(41, 41), seed=0):
    rng = np.random.default_rng(seed)
    height = (ndimage.gaussian_filter(rng.normal(size=shape), 3.0) * 15.0).astype(np.float32)
    observed = np.ones(shape, bool)
    observed[3:8, 30:36] = False  # a hole: masks must rotate too
    return make_bev(GridSpec((1.0, -2.0), 0.4, shape), height, observed, rng)


def rotated_bev(bev, times=1):
    """The BEV turned by times × 90° counter-clockwise (world) about its centre (square grid)."""
    def rot(a):
        return np.ascontiguousarray(np.rot90(a, times, axes=(-1, -2)))
    return type(bev)(bev.grid, rot(bev.channels), rot(bev.observed), rot(bev.counts))


def small_net(seed=0, **kwargs):
    torch.manual_seed(seed)
    model = eq.C8Net(("jeep", "vw_van"), **{"fields": 2, "depth": 1, "kernel": 5, **kwargs})
    return model.eval()


def test_filter_bank_is_closed_under_90_degrees():
    w = torch.randn(3, 2, 5, 5)
    bank = gc.rotated_filter_bank(w, gc.rotation_matrix_45(5))
    for r in range(8):
        assert torch.equal(bank[(r + 2) % 8], gc.rot90_world(bank[r])) or r >= 6


def test_rotating_the_map_by_90_degrees_shifts_the_headings_by_2_exactly():
    bev, model = hilly_bev(), small_net()
    out = eq.equivariant_locomotion(model, bev)  # (V, 8, H, W)
    out_rot = eq.equivariant_locomotion(model, rotated_bev(bev))
    expected = np.rot90(np.roll(out, 2, axis=1), 1, axes=(-1, -2))
    assert np.abs(out_rot - expected).max() < 1e-5
    assert np.ptp(out) > 0.05  # not a constant field


def test_45_degree_equivariance_error_is_small_but_not_zero():
    # A random (untrained) network on random terrain, |ΔL̂| at 200 cells: measured mean
    # 0.010–0.034 and max 0.16–0.54 over seeds 0–2 (outputs' std 0.03–0.22); 90°: < 1e-6.
    # The trained demo networks do far better (studies/eval_equivariant.py).
    err = eq.equivariance_error(small_net(), hilly_bev(), n=200)
    assert err["max_90"] < 1e-5
    assert 1e-4 < err["mean_45"] < 0.05 and err["max_45"] < 0.6


def slope_model(a=4.0, b=0.5):
    """A C8Net whose every channel is a known function: logit_k = b − a·∂H̄/∂θ_k (the
    1 × 1 slope filter needs no interpolation; ReLU(s) − ReLU(−s) = s)."""
    model = eq.C8Net(("jeep",), fields=2, depth=0, kernel=1).eval()
    with torch.no_grad():
        for p in (model.lift.weight, model.lift_slopes.weight, model.head.weight):
            p.zero_()
        model.lift_slopes.weight[0, 0, 0] = 1.0  # field 0: +slope
        model.lift_slopes.weight[1, 0, 0] = -1.0  # field 1: −slope
        model.head.weight[0, 0, 0] = -a
        model.head.weight[0, 1, 0] = a
        model.head.bias.fill_(b)
    return model


@pytest.mark.parametrize("direction_deg", [0, 90, 135])
def test_heading_convention_matches_the_literal_costmap_on_a_slope(direction_deg):
    grid = GridSpec((0.0, 0.0), 0.4, (50, 50))
    x, y = grid.cell_centers()
    alpha = np.radians(direction_deg)
    bev = synthetic_bev((0.2 * (np.cos(alpha) * x + np.sin(alpha) * y)).astype(np.float32))

    def literal(patches):  # the same function, read from heading-aligned 22 × 7 patches
        return 1 / (1 + np.exp(-(0.5 - 4.0 * forward_grade(patches))))[:, None]

    ref = directional_costmap_reference(bev, literal, 8, progress=False)[0]
    cost = eq.equivariant_costmap(bev, slope_model())[0]
    centre = (slice(None), slice(22, 28), slice(22, 28))  # > 2 half-patches from the edges
    assert np.abs(cost[centre] - ref[centre]).max() < 1e-3
    per_layer = cost[centre].mean(axis=(1, 2))
    assert np.argmax(per_layer) == round(direction_deg / 45) % 8  # uphill costs most


def test_one_pass_equals_per_heading_crops():
    bev, model = hilly_bev(), small_net(seed=1)
    out = eq.equivariant_locomotion(model, bev)  # (V, 8, H, W)
    rows, cols = np.meshgrid(np.arange(12, 30, 3), np.arange(12, 30, 3), indexing="ij")
    x, y = bev.grid.cell_to_xy(rows.ravel(), cols.ravel())
    for k in range(8):  # the map turned by −θ_k, channel 0, read back at the cell
        poses = np.stack([x, y, np.full(x.shape, 2 * np.pi * k / 8)], axis=1)
        per_heading = eq.predict_samples(model, bev, poses)  # (N, V)
        one_pass = out[:, k, rows.ravel(), cols.ravel()].T
        # even k: a 90° turn, exact; odd k: the 45° error (measured max 0.068 here)
        assert np.abs(per_heading - one_pass).max() < (1e-5 if k % 2 == 0 else 0.1)


def test_a_crop_at_heading_zero_is_the_map_itself():
    bev = hilly_bev()
    channels = eq.input_map(bev)
    x, y = bev.grid.cell_to_xy(20, 15)
    crop, seen = eq.heading_crops(channels, bev.observed, bev.grid, np.array([[x, y, 0.0]]), 9)
    np.testing.assert_allclose(crop[0], channels[:, 16:25, 11:20], atol=1e-6)
    assert np.array_equal(seen[0], bev.observed[16:25, 11:20])


def test_training_runs_and_keeps_the_split():
    bev = hilly_bev((50, 50))
    rng = np.random.default_rng(0)
    n = 96
    pose = np.stack([rng.uniform(4, 16, n), rng.uniform(2, 14, n), rng.uniform(0, 6.28, n)], 1)
    ds = PatchDataset(patches=np.zeros((n, 6, 22, 7), np.float16),
                      observed=np.ones((n, 22, 7), bool),
                      labels=rng.uniform(size=n).astype(np.float32),
                      vehicle=rng.integers(0, 4, n).astype(np.int8),
                      trajectory=np.arange(n, dtype=np.int32), pose=pose.astype(np.float32),
                      split=np.repeat(np.array([0, 1, 2], np.int8), n // 3))
    cfg = eq.EquivariantConfig(fields=2, depth=1, epochs=1, batch_size=16)
    result = eq.train_equivariant(ds, bev, cfg, seed=0, progress=False)
    assert result.best_epoch == 1 and set(result.metrics) <= {"jeep", "vw_van", "mercedes_van",
                                                               "carla_cola"}
    assert all(m["n"] > 0 for m in result.metrics.values())
    again = eq.EquivariantResult.from_dict(result.to_dict())
    np.testing.assert_array_equal(eq.equivariant_locomotion(again.model, bev),
                                  eq.equivariant_locomotion(result.model, bev))


def test_footprint_kernel_is_the_patch_turned_to_the_heading():
    k0 = eq.footprint_kernel(0.0)
    assert k0.sum() == pytest.approx(22 * 7)
    c = k0.shape[0] // 2
    assert k0[c, c - 10 : c + 11].min() == 1 and k0[c, c + 11] == 0.5  # 22 cells along +x
    assert k0[c - 3 : c + 4, c].min() == 1 and k0[c + 4, c] == 0  # 7 cells across
    np.testing.assert_allclose(eq.footprint_kernel(np.pi / 2), k0.T, atol=1e-12)
    assert eq.footprint_kernel(np.pi / 4).sum() == pytest.approx(154, rel=0.03)
    field = np.full((1, 8, 30, 30), 0.7, np.float32)
    np.testing.assert_allclose(eq.footprint_average(field, np.ones((30, 30), bool)), field,
                               rtol=1e-6)


def test_training_crops_see_the_slope_of_the_pose_heading():
    # the crops training and evaluation use turn ∇H̄ with the map: any θ, not only the bins
    grid = GridSpec((0.0, 0.0), 0.4, (50, 50))
    x, y = grid.cell_centers()
    alpha, slope = np.radians(60), 0.2
    bev = synthetic_bev((slope * (np.cos(alpha) * x + np.sin(alpha) * y)).astype(np.float32))
    theta = np.radians([0, 30, 60, 100, 240, 300])
    poses = np.stack([np.full(6, 10.0), np.full(6, 10.0), theta], 1)
    pred = eq.predict_samples(slope_model(), bev, poses)[:, 0]
    expected = 1 / (1 + np.exp(-(0.5 - 4.0 * slope * np.cos(theta - alpha))))
    np.testing.assert_allclose(pred, expected, atol=1e-5)
