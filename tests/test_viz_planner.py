"""The computing parts of dgt_lib.viz's planner figures: the primitive / layer lookup
drawn in notebook 05 must be the one the planner prices its moves with."""

import dataclasses
import math

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest

from dgt_lib import viz
from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.geometry import GridSpec
from dgt_lib.navigation.planner import HybridAStar, PlanResult, amplified_cost, edge_cost

K = 8
GRID = GridSpec((0.0, 0.0), 0.4, (100, 100))
R_MIN = 5.7


def test_straight_moves_read_the_layer_of_their_heading():
    for k in range(K):
        theta = 2 * math.pi * k / K
        look = viz.primitive_lookups((20.2, 20.2, theta), R_MIN, GRID, K)
        assert look["straight"]["k"] == k
        assert look["straight"]["d_cell"] != (0, 0)


def test_lookup_follows_the_cell_move_not_the_heading():
    # heading 20°, nearest layer 0 (0°); but from this pose the straight arc's end cell
    # lies 2 rows up and 4 columns right: θ' = atan2(2, 4) = 27°, nearest layer 1 (45°)
    look = viz.primitive_lookups((20.1, 19.9, math.radians(20.0)), R_MIN, GRID, K)
    straight = look["straight"]
    assert straight["d_cell"] == (2, 4)
    assert straight["theta"] == pytest.approx(math.atan2(2, 4))
    assert straight["k"] == 1
    assert len(straight["substeps"]) == 8  # 1.6 m at 0.2 m sub-steps
    assert np.allclose(straight["substeps"][-1, :2],
                       (20.1 + 1.6 * math.cos(math.radians(20.0)),
                        19.9 + 1.6 * math.sin(math.radians(20.0))))


@pytest.mark.parametrize("primitive", viz.PRIMITIVES)
@pytest.mark.parametrize("heading_deg", [0.0, 20.0, 30.0, 80.0, 200.0, 315.0])
def test_drawn_layer_is_the_layer_the_planner_prices(primitive, heading_deg):
    """Layer k costs 0.1·(k + 1); a one-primitive query's cost reveals the layer read."""
    costmap = np.broadcast_to(0.1 * (np.arange(K) + 1.0)[:, None, None], (K, *GRID.shape))
    cfg = dataclasses.replace(PlannerConfig(), analytic_shot=False, goal_tolerance_m=0.05)
    planner = HybridAStar(costmap, np.zeros(GRID.shape, np.uint8), GRID,
                          min_turn_radius_m=R_MIN, footprint=(4.0, 2.0), cfg=cfg)
    start = (20.1, 19.9, math.radians(heading_deg))
    look = viz.primitive_lookups(start, R_MIN, GRID, K, step_m=cfg.step_m,
                                 substep_m=cfg.substep_m)[primitive]
    result = planner.plan(start, tuple(look["substeps"][-1, :2]))
    assert result.success and len(result.nodes) == 2
    expected = edge_cost(cfg.step_m, amplified_cost(0.1 * (look["k"] + 1), cfg.beta))
    assert result.cost == pytest.approx(expected)


def test_bad_radius_is_refused():
    with pytest.raises(ValueError, match="min_turn_radius_m"):
        viz.primitive_lookups((1.0, 1.0, 0.0), 0.0, GRID, K)


def test_plan_table_lists_each_plan_and_marks_failures():
    ok = PlanResult(path=np.array([[0.0, 0.0, 0.0], [3.0, 4.0, 0.0]]), cost=12.5,
                    expansions=7, time_s=0.25, success=True, reason="reached goal")
    failed = PlanResult(path=np.zeros((0, 3)), cost=math.inf, expansions=99, time_s=1.0,
                        success=False, reason="no path exists", failure="no_path")
    table = viz.plan_table({"euclidean": ok, "cost-to-go": failed}).splitlines()
    assert len(table) == 4
    assert table[2] == "| euclidean | yes | 7 | 0.25 | 12.5 | 5.0 |"
    assert table[3] == "| cost-to-go | no | 99 | 1.00 | — | — |"


def test_expansion_table_and_figure_show_every_primitive_of_each_step():
    import itertools
    import types

    from dgt_lib.viz.planner import expansion_table, plot_expansions

    costmap = np.broadcast_to(0.1 * (np.arange(K) + 1.0)[:, None, None], (K, *GRID.shape))
    occupancy = np.zeros(GRID.shape, np.uint8)
    occupancy[40:60, 55:60] = 1  # a wall ahead (x 22–24 m, y 16–24 m)
    planner = HybridAStar(costmap, occupancy, GRID, min_turn_radius_m=R_MIN,
                          footprint=(4.0, 2.0), cfg=PlannerConfig(heuristic="euclidean"))
    search = planner.search((15.0, 20.0, 0.0), (35.0, 20.0))
    search.push_start()
    steps = list(itertools.islice(search.steps(), 12))
    rows = expansion_table(steps).splitlines()[2:]
    assert len(rows) == 3 * len(steps) == 36
    assert rows[0].startswith("| 0 | (15.0, 20.0), 0.00 | straight |")
    assert all(r.endswith(("| pushed |", "| collides |", "| closed |", "| not cheaper |"))
               for r in rows)
    world = types.SimpleNamespace(heights=np.zeros(GRID.shape), resolution=GRID.resolution,
                                  extent=GRID.extent)
    fig = plot_expansions(world, steps)
    segments = [line for line in fig.axes[0].lines if len(line.get_xdata()) == 2]
    assert len(segments) == 3 * len(steps)
