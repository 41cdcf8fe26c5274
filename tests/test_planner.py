"""Direction-aware Hybrid A* (dgt_lib.navigation.planner) on small synthetic maps."""

import math

import numpy as np
import pytest

from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.geometry import GridSpec, angle_diff
from dgt_lib.core.vehicle_spec import footprint_circles
from dgt_lib.navigation.planner import (
    HybridAStar,
    InvalidQueryError,
    amplified_cost,
    dubins_path,
    edge_cost,
    sample_segments,
    travel_heading_bin,
    turn_then_straight,
)

RES = 0.5
R_MIN = 4.0
FOOTPRINT = (4.0, 2.0)
K = 8


def empty_map(width_m=60.0, height_m=40.0):
    grid = GridSpec((0.0, 0.0), RES, (int(height_m / RES), int(width_m / RES)))
    return np.zeros((K, *grid.shape)), np.zeros(grid.shape, dtype=np.uint8), grid


@pytest.fixture(scope="module")
def hill():
    """A hill-like 80 m × 60 m map: low ground y < 25, a plateau y > 35, a wall in
    between with two gaps. Route B (x 34–46, straight between start and goal) is
    steep: expensive uphill (+y) and across, cheap downhill. Route A (x 62–74) is
    a longer detour that is cheap in every direction."""
    grid = GridSpec((0.0, 0.0), RES, (120, 160))
    X, Y = grid.cell_centers()
    band = (Y > 25.0) & (Y < 35.0)
    gap_b = band & (X > 34.0) & (X < 46.0)
    gap_a = band & (X > 62.0) & (X < 74.0)
    occupancy = (band & ~gap_a & ~gap_b).astype(np.uint8)
    costmap = np.full((K, *grid.shape), 0.02)
    theta = 2 * np.pi * np.arange(K) / K
    uphill_or_across = np.sin(theta) > -0.1  # layers 0..4: +y component or across
    costmap[:, gap_b] = np.where(uphill_or_across[:, None], 0.8, 0.05)
    costmap[:, gap_a] = 0.05
    return costmap, occupancy, grid


def route(path: np.ndarray) -> str:
    """"A" or "B": where the path crosses the wall band (y = 30)."""
    crossing = path[np.argmin(np.abs(path[:, 1] - 30.0)), 0]
    return "B" if abs(crossing - 40.0) < 7.0 else "A"


def planner_for(costmap, occupancy, grid, **cfg):
    return HybridAStar(costmap, occupancy, grid, min_turn_radius_m=R_MIN, footprint=FOOTPRINT,
                       cfg=PlannerConfig(**cfg))


ASCENT = ((40.0, 8.0, math.pi / 2), (40.0, 52.0))
DESCENT = ((40.0, 52.0, -math.pi / 2), (40.0, 8.0))


def assert_feasible(result, planner, start, goal, occupancy, grid):
    """Starts at the start, ends at the goal, is collision-free for the real rectangle,
    turns no tighter than r_min and drives along its headings."""
    path = result.path
    assert result.success and result.reason == "reached goal"
    np.testing.assert_allclose(path[0, :2], start[:2])
    assert np.hypot(*(path[-1, :2] - np.asarray(goal[:2]))) <= planner.cfg.goal_tolerance_m + 1e-9
    # no occupied cell centre inside the vehicle rectangle at any sample; all samples on the map
    assert grid.contains(path[:, 0], path[:, 1]).all()
    rows, cols = np.nonzero(occupancy)
    ox, oy = grid.cell_to_xy(rows, cols)
    for x, y, th in path:
        near = np.hypot(ox - x, oy - y) < 5.0
        lon = (ox[near] - x) * np.cos(th) + (oy[near] - y) * np.sin(th)
        lat = -(ox[near] - x) * np.sin(th) + (oy[near] - y) * np.cos(th)
        assert not np.any((np.abs(lon) < FOOTPRINT[0] / 2) & (np.abs(lat) < FOOTPRINT[1] / 2))
    # curvature |dθ/ds| ≤ 1/r_min and motion along the heading
    step = np.diff(path[:, :2], axis=0)
    ds = np.hypot(*step.T)
    assert ds.max() <= planner.cfg.substep_m + 1e-9 and ds.min() > 0
    dtheta = angle_diff(path[1:, 2], path[:-1, 2])
    assert np.all(np.abs(dtheta) / ds <= (1.0 / R_MIN) * (1 + 1e-3))
    motion = np.arctan2(step[:, 1], step[:, 0])
    mid = path[:-1, 2] + dtheta / 2
    assert np.all(np.abs(angle_diff(motion, mid)) < 1e-6)


# --- the paper's cost model ----------------------------------------------------------------


def test_travel_direction_convention_rows_are_y():
    assert travel_heading_bin(0, 3, 8) == 0  # Δcol > 0: +x → layer 0
    assert travel_heading_bin(3, 0, 8) == 2  # Δrow > 0: +y → layer K/4
    assert travel_heading_bin(0, -3, 8) == 4
    assert travel_heading_bin(-3, 0, 8) == 6
    assert travel_heading_bin(2, 2, 8) == 1
    assert travel_heading_bin(3, 1, 8) == 2  # 71.6° → nearest 90°
    assert travel_heading_bin(5, 0, 4) == 1  # K/4 for K = 4 too
    assert travel_heading_bin(1, 9, 1) == 0


def test_amplified_and_edge_cost_follow_the_paper():
    assert amplified_cost(0.5, 150.0) == pytest.approx(0.5 * (1 + 75.0))
    assert amplified_cost(0.0, 150.0) == 0.0
    assert edge_cost(1.6, 38.0) == pytest.approx(1.6 * 39.0)


@pytest.mark.parametrize("layer, heading, goal, expensive", [
    (0, 0.0, (50.0, 20.25), True),            # +x travel reads layer 0
    (0, math.pi / 2, (10.25, 35.0), False),   # +y travel does not
    (2, math.pi / 2, (10.25, 35.0), True),    # +y travel reads layer K/4
    (2, 0.0, (50.0, 20.25), False),
])
def test_directional_layer_used_for_travel_direction(layer, heading, goal, expensive):
    costmap, occupancy, grid = empty_map()
    costmap[layer] = 0.02  # C' = 0.02 (1 + 150·0.02) = 0.08 per metre
    start = (10.25, 20.25, heading) if heading == 0.0 else (10.25, 5.25, heading)
    result = planner_for(costmap, occupancy, grid).plan(start, goal)
    assert result.success
    rate = 1.08 if expensive else 1.0
    assert result.cost == pytest.approx(rate * result.length_m, rel=1e-9)
    assert np.ptp(result.path[:, 2]) == 0.0  # a straight line


# --- route choice on the synthetic hill ----------------------------------------------------


@pytest.mark.parametrize("heuristic", ["cost_to_go", "euclidean"])
def test_directional_costmap_ascends_route_a_and_descends_route_b(hill, heuristic):
    costmap, occupancy, grid = hill
    planner = planner_for(costmap, occupancy, grid, heuristic=heuristic)
    up = planner.plan(*ASCENT)
    down = planner.plan(*DESCENT)
    assert route(up.path) == "A"
    assert route(down.path) == "B"
    for result, (start, goal) in ((up, ASCENT), (down, DESCENT)):
        assert_feasible(result, planner, start, goal, occupancy, grid)


def test_isotropic_costmap_takes_the_same_route_both_ways(hill):
    costmap, occupancy, grid = hill
    isotropic = costmap.mean(axis=0, keepdims=True)
    planner = planner_for(isotropic, occupancy, grid)
    up, down = planner.plan(*ASCENT), planner.plan(*DESCENT)
    assert route(up.path) == route(down.path) == "A"


def test_zero_cost_and_beta_zero_give_the_shortest_route(hill):
    costmap, occupancy, grid = hill
    for cm, beta in ((np.zeros_like(costmap), 150.0), (costmap, 0.0)):
        planner = planner_for(cm, occupancy, grid, beta=beta)
        up, down = planner.plan(*ASCENT), planner.plan(*DESCENT)
        assert route(up.path) == route(down.path) == "B"
    # zero cost: the cost is the path length (arc length; the polyline of samples is a hair
    # shorter on arcs), within a step of the straight distance
    planner = planner_for(np.zeros_like(costmap), occupancy, grid)
    up = planner.plan(*ASCENT)
    assert up.cost == pytest.approx(up.length_m, rel=1e-4)
    assert up.length_m <= 44.0 + 1.6


def test_straight_shot_on_an_empty_map_is_the_straight_line():
    costmap, occupancy, grid = empty_map()
    result = planner_for(costmap, occupancy, grid).plan((5.0, 20.0, 0.0), (55.0, 20.0))
    assert result.cost == pytest.approx(50.0, abs=1.6)
    assert result.length_m == pytest.approx(result.cost)
    np.testing.assert_allclose(result.path[:, 1], 20.0)


# --- admissibility of the heuristic --------------------------------------------------------


@pytest.mark.parametrize("query", [ASCENT, DESCENT])
def test_cost_to_go_never_exceeds_the_remaining_path_cost(hill, query):
    costmap, occupancy, grid = hill
    planner = planner_for(costmap, occupancy, grid, heuristic="euclidean", analytic_shot=False)
    result = planner.plan(*query)
    h = planner.cost_to_go(query[1])
    rows, cols = grid.xy_to_cell(result.nodes[:, 0], result.nodes[:, 1])
    remaining = result.cost - result.node_costs
    assert np.all(h[rows, cols] <= remaining + 1e-9)
    assert h[rows[0], cols[0]] > 0.3 * result.cost  # and it is not trivially zero


# --- goal poses, analytic shots, footprint -------------------------------------------------


def test_goal_with_heading_is_reached_with_that_heading():
    costmap, occupancy, grid = empty_map()
    planner = planner_for(costmap, occupancy, grid)
    result = planner.plan((10.0, 10.0, 0.0), (40.0, 25.0, math.pi))
    assert result.success
    assert abs(angle_diff(result.path[-1, 2], math.pi)) <= planner.cfg.goal_heading_tolerance_rad
    assert_feasible(result, planner, (10.0, 10.0, 0.0), (40.0, 25.0), occupancy, grid)


def test_dubins_and_turn_then_straight_end_where_asked():
    rng = np.random.default_rng(0)
    words = set()
    for _ in range(200):
        start = (*rng.uniform(-20, 20, 2), rng.uniform(0, 2 * np.pi))
        goal = (*rng.uniform(-20, 20, 2), rng.uniform(0, 2 * np.pi))
        segments = dubins_path(start, goal, 3.0)
        words.add("".join(kind for kind, _ in segments))
        end = sample_segments(start, segments, 3.0, 0.1)[-1]
        np.testing.assert_allclose(end[:2], goal[:2], atol=1e-6)
        assert abs(angle_diff(end[2], goal[2])) < 1e-6
        cs = turn_then_straight(start, goal[:2], 3.0)
        if cs is not None:
            end = sample_segments(start, cs, 3.0, 0.1)[-1]
            np.testing.assert_allclose(end[:2], goal[:2], atol=1e-6)
            # a CS path is one of Dubins' words: the Dubins path to its end pose is no longer
            best = dubins_path(start, end, 3.0)
            assert sum(v for _, v in best) <= sum(v for _, v in cs) + 1e-6
    assert {"LSL", "RSR", "LSR", "RSL"} <= words


def test_footprint_circles_cover_the_rectangle():
    offsets, radius = footprint_circles(6.4, 2.4)
    assert len(offsets) % 2 == 1 and 0.0 in offsets
    rng = np.random.default_rng(1)
    pts = rng.uniform([-3.2, -1.2], [3.2, 1.2], (2000, 2))
    dist = np.hypot(pts[:, :1] - offsets[None, :], pts[:, 1:])
    assert np.all(dist.min(axis=1) <= radius + 1e-12)


# --- errors, bounds, determinism -----------------------------------------------------------


def test_start_in_obstacle_or_off_map_is_a_clear_error(hill):
    costmap, occupancy, grid = hill
    planner = planner_for(costmap, occupancy, grid)
    with pytest.raises(InvalidQueryError, match="start .* obstacle"):
        planner.plan((20.0, 30.0, 0.0), (40.0, 52.0))
    with pytest.raises(InvalidQueryError, match="goal .* off the map"):
        planner.plan((40.0, 8.0, 0.0), (40.0, 90.0))
    with pytest.raises(InvalidQueryError, match="goal .* occupied"):
        planner.plan((40.0, 8.0, 0.0), (20.0, 30.0))
    with pytest.raises(ValueError, match="heuristic"):
        planner_for(costmap, occupancy, grid, heuristic="manhattan")


def test_a_rejected_query_says_whether_it_hit_unobserved_or_occupied_ground():
    """A start on terrain the BEV map never saw is not 'in an obstacle' like a cliff: the
    message must say which, or a user chases a slope that is not there."""
    costmap, occupancy, grid = empty_map()
    occupancy[:, :40] = 2  # x < 20 m: unobserved
    occupancy[:, 80:] = 1  # x ≥ 40 m: too steep
    planner = planner_for(costmap, occupancy, grid)
    with pytest.raises(InvalidQueryError, match="start .* obstacle") as unseen:
        planner.plan((10.0, 20.0, 0.0), (30.0, 20.0))
    assert "hits unobserved cells" in str(unseen.value) and "occupied" not in str(unseen.value)
    with pytest.raises(InvalidQueryError, match="start .* obstacle") as steep:
        planner.plan((50.0, 20.0, 0.0), (30.0, 20.0))
    assert "hits occupied cells" in str(steep.value) and "unobserved" not in str(steep.value)
    with pytest.raises(InvalidQueryError, match="goal .* unobserved cells"):
        planner.plan((30.0, 20.0, 0.0), (10.0, 20.0))
    with pytest.raises(InvalidQueryError, match="start .* the map edge"):
        planner.plan((30.0, 0.5, math.pi / 2), (30.0, 20.0))


def test_unreachable_goal_ends_with_no_path(hill):
    costmap, occupancy, grid = hill
    closed = occupancy.copy()
    X, Y = grid.cell_centers()
    closed[(Y > 25.0) & (Y < 35.0)] = 1  # wall off both gaps
    # the 2D relaxation refutes it before any expansion
    result = planner_for(costmap, closed, grid).plan(*ASCENT)
    assert not result.success and result.reason.startswith("no path exists")
    assert "relaxation" in result.reason and result.expansions == 0
    assert result.failure == "no_path"
    assert result.path.shape == (0, 3) and result.cost == math.inf
    # the Euclidean search expands every reachable pose of a small pen, then gives up
    pen = closed.copy()
    pen[(Y < 25.0) & ((X < 25.0) | (X > 55.0))] = 1
    planner = planner_for(costmap, pen, grid, heuristic="euclidean", closed_cell_m=1.6,
                          theta_bins=36)
    result = planner.plan(*ASCENT)
    assert not result.success and "open list exhausted" in result.reason
    assert result.failure == "no_path"
    # and a cap bounds any search: the budget, not a proof that no path exists
    planner = planner_for(costmap, closed, grid, heuristic="euclidean", max_expansions=500)
    result = planner.plan(*ASCENT)
    assert not result.success and "planner.max_expansions=500" in result.reason
    assert result.failure == "budget" and result.reason.startswith("search budget exhausted")
    assert result.expansions == 500


def test_deterministic(hill):
    costmap, occupancy, grid = hill
    a = planner_for(costmap, occupancy, grid).plan(*ASCENT)
    b = HybridAStar(costmap, occupancy, grid, min_turn_radius_m=R_MIN,
                    footprint=FOOTPRINT).plan(*ASCENT)  # another planner, the same plan
    np.testing.assert_array_equal(a.path, b.path)
    assert a.cost == b.cost and a.expansions == b.expansions


def test_world_hill_ascends_route_a_and_descends_route_b():
    """On the Experiment 1 hill, with a directional cost from the true slopes
    (uphill grade² + cross grade²), carla_cola-sized, the planner climbs Route A and
    comes down Route B."""
    from dgt_lib.world.terrain import make_hill

    world = make_hill(0.4, 0)
    gx, gy = world.gradient()
    theta = 2 * np.pi * np.arange(K) / K
    grade = gx[None] * np.cos(theta)[:, None, None] + gy[None] * np.sin(theta)[:, None, None]
    cross = -gx[None] * np.sin(theta)[:, None, None] + gy[None] * np.cos(theta)[:, None, None]
    costmap = np.clip(0.05 + 2.0 * np.maximum(grade, 0.0) ** 2 + cross**2, 0.0, 1.0)
    occupancy = (np.hypot(gx, gy) > 1.0).astype(np.uint8)
    planner = HybridAStar(costmap, occupancy, world.grid, min_turn_radius_m=5.71,
                          footprint=(6.4, 2.4), cfg=PlannerConfig(heuristic_weight=1.5))
    base, summit = world.landmarks["base"], world.landmarks["summit"]
    up = planner.plan((*base, math.pi / 2), summit)
    down = planner.plan((*summit, -math.pi / 2), base)
    corner = np.asarray(world.landmarks["A_corner"])
    steep = np.asarray(world.landmarks["B_steep_bottom"])  # Route B's steep section starts here
    assert up.success and down.success
    assert np.hypot(*(up.path[:, :2] - corner).T).min() < 10.0  # round Route A's corner
    assert np.hypot(*(down.path[:, :2] - steep).T).min() < 5.0  # straight down Route B
    assert down.length_m < 100.0 < 200.0 < up.length_m


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, -0.1, 1.1])
def test_a_costmap_value_outside_zero_to_one_is_a_clear_error(bad):
    costmap, occupancy, grid = empty_map()
    costmap[3, 10, 20] = bad
    with pytest.raises(ValueError, match="finite and in"):
        HybridAStar(costmap, occupancy, grid, min_turn_radius_m=R_MIN, footprint=FOOTPRINT)


@pytest.mark.parametrize("dtype", [np.uint8, np.int64, np.float64])
def test_an_occupancy_value_other_than_0_1_2_is_a_clear_error(dtype):
    costmap, occupancy, grid = empty_map()
    occupancy = occupancy.astype(dtype)
    occupancy[10, 20] = 2
    HybridAStar(costmap, occupancy, grid, min_turn_radius_m=R_MIN, footprint=FOOTPRINT)
    for bad in {np.uint8: (3, 255), np.int64: (3, -1), np.float64: (3, -1, 0.5)}[dtype]:
        occupancy[10, 20] = bad
        with pytest.raises(ValueError, match="occupancy values must be 0"):
            HybridAStar(costmap, occupancy, grid, min_turn_radius_m=R_MIN, footprint=FOOTPRINT)
