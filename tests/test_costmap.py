import numpy as np
import pytest

from dgt_lib.core.geometry import GridSpec
from dgt_lib.mapping.costmap import directional_costmap, directional_costmap_reference
from dgt_lib.mapping.occupancy import OCCUPIED, UNOBSERVED, occupancy_map, select_tau_s
from dgt_lib.perception.bev import BEVMap, height_gradient
from dgt_lib.perception.patches import PATCH_COLS, PATCH_ROWS


def synthetic_bev(heights: np.ndarray, observed: np.ndarray | None = None) -> BEVMap:
    grid = GridSpec((0.0, 0.0), 0.4, heights.shape)
    observed = np.ones(heights.shape, bool) if observed is None else observed
    channels = np.zeros((6, *heights.shape), np.float32)
    channels[1] = 0.5
    channels[3] = heights
    channels[5] = height_gradient(heights.astype(np.float32), observed, 0.4)
    channels[:, ~observed] = 0.0
    return BEVMap(grid, channels, observed, observed.astype(np.int64))


def slope_predictor(patches: np.ndarray) -> np.ndarray:
    """Two 'vehicles': L falls with the forward rise of H̄ (row 0 is ahead), one weak, one strong."""
    h = patches[:, 3]
    rise = (h[:, :3].mean(axis=(1, 2)) - h[:, -3:].mean(axis=(1, 2))) / (0.4 * (PATCH_ROWS - 3))
    weak = np.exp(-np.clip(rise, 0, None) * 8.0)
    strong = np.exp(-np.clip(rise, 0, None) * 2.0)
    return np.stack([weak, strong], axis=1)


def ramp(shape=(60, 50), slope=0.3):
    grid = GridSpec((0.0, 0.0), 0.4, shape)
    x, y = grid.cell_centers()
    return (slope * x).astype(np.float32)


def test_layer_zero_is_plus_x_and_layers_turn_counter_clockwise():
    bev = synthetic_bev(ramp((70, 70)))  # rises toward +x
    cost = directional_costmap_reference(bev, slope_predictor, 8, progress=False)
    assert cost.shape == (2, 8, 70, 70)
    centre = (slice(27, 43), slice(27, 43))  # > one patch length from every edge
    per_layer = cost[0][(slice(None), *centre)].mean(axis=(1, 2))
    assert per_layer[0] == per_layer.max()  # driving +x is uphill
    assert per_layer[4] < 0.01  # driving −x is downhill: free for this predictor
    assert per_layer[2] == pytest.approx(per_layer[6], abs=0.02)  # ±y are level
    assert per_layer[1] > per_layer[2] and per_layer[7] > per_layer[6]  # 45° is partly uphill
    # the weak climber pays more than the strong one uphill
    assert cost[0, 0][centre].mean() > cost[1, 0][centre].mean() + 0.2


def test_layer_for_plus_y_on_a_ramp_rising_north():
    grid = GridSpec((0.0, 0.0), 0.4, (70, 70))
    _, y = grid.cell_centers()
    bev = synthetic_bev((0.3 * y).astype(np.float32))
    cost = directional_costmap_reference(bev, slope_predictor, 4, progress=False)
    per_layer = cost[0][:, 27:43, 27:43].mean(axis=(1, 2))
    assert np.argmax(per_layer) == 1  # θ = π/2 (+y, north) is uphill


def test_fast_path_matches_the_literal_one():
    rng = np.random.default_rng(0)
    base = ramp((70, 60), 0.15)
    bumps = np.zeros_like(base)
    for _ in range(6):
        r, c = rng.integers(10, 60, 2)
        bumps[max(r - 4, 0) : r + 4, max(c - 4, 0) : c + 4] += rng.uniform(0.5, 1.5)
    import cv2

    bev = synthetic_bev(base + cv2.GaussianBlur(bumps, (0, 0), 3))
    ref = directional_costmap_reference(bev, slope_predictor, 8, progress=False)
    fast = directional_costmap(bev, slope_predictor, 8, stride=(4, 2), progress=False)
    assert np.abs(fast - ref).mean() <= 0.02


def test_stride_one_without_skipping_is_exactly_the_reference():
    bev = synthetic_bev(ramp((40, 40)))
    ref = directional_costmap_reference(bev, slope_predictor, 2, progress=False)
    same = directional_costmap(bev, slope_predictor, 2, stride=(1, 1), skip_unobserved=False,
                               progress=False)
    np.testing.assert_array_equal(ref, same)


def test_unobserved_cells_cost_one_and_skipping_them_changes_nothing_observed():
    observed = np.ones((50, 50), bool)
    observed[:, 35:] = False
    bev = synthetic_bev(ramp((50, 50)), observed)
    ref = directional_costmap(bev, slope_predictor, 4, stride=(1, 1), skip_unobserved=False,
                              progress=False)
    skip = directional_costmap(bev, slope_predictor, 4, stride=(1, 1), skip_unobserved=True,
                               progress=False)
    assert (ref[:, :, ~observed] == 1).all() and (skip[:, :, ~observed] == 1).all()
    np.testing.assert_allclose(skip, ref, atol=1e-6)


def test_occupancy_marks_steep_steps_and_unobserved():
    heights = np.zeros((30, 30), np.float32)
    heights[10:13, 10:13] = 3.0  # a 'tree' column
    observed = np.ones((30, 30), bool)
    observed[0, :] = False
    bev = synthetic_bev(heights, observed)
    occ = occupancy_map(bev, tau_s=1.0)
    assert (occ[11, 11 - 2 : 11 + 3] == OCCUPIED).any()
    assert (occ[0] == UNOBSERVED).all()
    assert (occ[20:, 20:] == 0).all()


def test_tau_s_keeps_every_traversed_cell_free():
    g = np.array([0.1, 0.35, 0.2, np.nan])
    tau = select_tau_s(g)
    assert tau > 0.35 and tau < 0.4
    with pytest.raises(ValueError):
        select_tau_s(np.array([np.nan]))


def test_windows_fit_the_patch_definition():
    assert (PATCH_ROWS, PATCH_COLS) == (22, 7)


def test_world_maps_cost_at_reads_the_nearest_heading_layer_of_the_cell():
    """Paper (Directional Cost Lookup): C at (x, y) travelled at θ is layer
    k* = argmin_k |θ_k − θ| of the cell's costs; points off the map clamp to its edge."""
    from dgt_lib.mapping.world_maps import WorldMaps
    from dgt_lib.perception.bev import N_CHANNELS

    grid = GridSpec((0.0, 0.0), 0.4, (10, 20))
    bev = BEVMap(grid, np.zeros((N_CHANNELS, 10, 20), np.float32), np.ones((10, 20), bool),
                 np.ones((10, 20), np.int64))
    cost = np.zeros((8, 10, 20), np.float32)
    cost += (np.arange(8) / 10.0)[:, None, None]  # layer k costs k / 10
    cost[:, 3, 7] += 0.05  # one cell stands out
    maps = WorldMaps("toy", bev, np.zeros((10, 20), np.int8), 0.5, {("dgt", "jeep"): cost})
    x, y = 7 * 0.4 + 0.2, 3 * 0.4 + 0.2  # the centre of cell (3, 7)
    got = maps.cost_at("dgt", "jeep", [x, x, x, x], [y] * 4,
                       [0.0, np.pi / 2, np.pi + 0.3, -0.1])
    np.testing.assert_allclose(got, [0.05, 0.25, 0.45, 0.05], atol=1e-6)
    np.testing.assert_allclose(maps.cost_at("dgt", "jeep", -50.0, 100.0, np.pi), 0.4)
