"""The reference search as a notebook steps through it (pop, expand the primitives, the
directional lookup, push), a learner's edge cost plugged into the planner, and the
planner package's shape (no import cycle between its modules)."""

import ast
import math
from pathlib import Path

import numpy as np

from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.geometry import nearest_heading_bin
from dgt_lib.navigation.planner import (
    HybridAStar,
    search,
    step_cost,
    travel_heading_bin,
)
from dgt_lib.navigation.planner.primitives import PrimitiveSet
from tests import planner_cases
from tests.test_planner_exact import same_plan

UP = ((40.0, 8.0, math.pi / 2), (40.0, 52.0))


def _hill_planner(cfg=None, **kwargs):
    costmap, occupancy, grid = planner_cases.hill_maps()
    return HybridAStar(costmap, occupancy, grid, cfg=cfg or PlannerConfig(),
                       **planner_cases.HILL, **kwargs)


def test_stepping_the_search_is_the_plan():
    """Every step pops one node and prices its three primitives; the nodes popped, in
    order, are the plan's expanded nodes, and the goal ends the steps."""
    planner = _hill_planner()
    result = planner.plan(*UP)
    s = planner.search(*UP)
    assert s.push_start()
    steps = list(s.steps())
    assert [(e.node.x, e.node.y) for e in steps] == [tuple(p) for p in result.expanded_xy]
    assert s.goal is not None and s.goal.g == result.cost
    costmap = planner.maps.costmap
    for e in steps[:200]:
        assert [p.primitive for p in e.primitives] == [0, 1, 2]
        for p in e.primitives:
            if p.outcome in (search.COLLIDES, search.CLOSED):
                continue
            # the directional lookup: the layer of the cell move, C read there
            d_row, d_col = p.row - e.node.row, p.col - e.node.col
            if (d_row, d_col) != (0, 0):
                assert p.layer == travel_heading_bin(d_row, d_col, costmap.shape[0])
            assert p.cost == costmap[p.layer, p.row, p.col]
            assert p.g == e.node.g + step_cost(1.6, p.cost, 150.0)
    outcomes = {p.outcome for e in steps for p in e.primitives}
    assert {search.PUSHED, search.COLLIDES, search.CLOSED} <= outcomes


def test_the_papers_edge_cost_plugged_in_is_the_default_plan_to_the_bit():
    default = _hill_planner().plan(*UP)
    plugged = _hill_planner(edge_cost=step_cost).plan(*UP)
    assert default.success and same_plan(default, plugged)


def test_a_learners_edge_cost_drives_the_plan():
    """With the paper's Euclidean heuristic the edge cost alone decides: without β's
    amplification the steep gap (cost 0.8 uphill) is cheap enough, and the plan goes
    through it (34 < x < 46) instead of the gentle gap (62 < x < 74)."""
    cfg = PlannerConfig(heuristic="euclidean")
    default = _hill_planner(cfg=cfg).plan(*UP)
    linear = _hill_planner(cfg=cfg, edge_cost=lambda s, c, beta: s * (1.0 + c)).plan(*UP)
    crossing = lambda r: r.path[np.argmin(np.abs(r.path[:, 1] - 30.0)), 0]  # noqa: E731
    assert default.success and 62.0 < crossing(default) < 74.0
    assert linear.success and 34.0 < crossing(linear) < 46.0


def test_successor_reads_the_layer_of_the_cell_move_or_of_the_mid_arc_heading():
    """PrimitiveSet.successor, the search's and the figures' directional lookup: k* of the
    cell move, or of the arc's mid heading when the move keeps its cell (2 m cells: a
    1.6 m step often does)."""
    kept = 0
    for res in (0.4, 2.0):
        ps = PrimitiveSet(0.3, step_m=1.6, min_turn_radius_m=4.0, substep_m=0.2,
                          circle_offsets=np.zeros(1), resolution=res, theta_bins=36,
                          n_headings=8, origin_xy=(0.0, 0.0))
        for n in range(-8, 9):
            for x in np.linspace(10.05, 11.95, 7):
                row, col = int(10.5 / res), int(x / res)
                for j in range(3):
                    end = ps.successor(x, 10.5, n, row, col, j)
                    d = (end.row - row, end.col - col)
                    if d == (0, 0):
                        kept += 1
                        mid = ps.heading(n) + (0, 1, -1)[j] * ps.dtheta / 2
                        assert end.layer == nearest_heading_bin(mid, 8)
                    else:
                        assert end.layer == travel_heading_bin(*d, 8)
    assert kept > 0


def _planner_imports(path: Path) -> set[str]:
    """The planner modules a module imports, anywhere in it (TYPE_CHECKING, functions)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            if node.module.startswith("dgt_lib.navigation.planner."):
                out.add(node.module.rsplit(".", 1)[1])
            elif node.module == "dgt_lib.navigation.planner":
                out.update(a.name for a in node.names)
    return out


def test_planner_modules_import_no_cycle_and_stay_small():
    package = Path(search.__file__).parent
    modules = {p.stem: p for p in package.glob("*.py") if p.stem != "__init__"}
    graph = {name: _planner_imports(p) & set(modules) for name, p in modules.items()}
    done, active = set(), []

    def visit(name):
        assert name not in active, f"import cycle: {' → '.join(active + [name])}"
        if name in done:
            return
        active.append(name)
        for dep in graph[name]:
            visit(dep)
        active.pop()
        done.add(name)

    for name in graph:
        visit(name)
    for name, path in modules.items():
        assert len(path.read_text().splitlines()) <= 500, name


def test_notebook_05s_solution_is_right_and_plans_the_librarys_plan():
    """The reference solution of notebook 05's edge-cost exercise grades right and, plugged
    into the planner as the notebook does, gives the library's plan to the bit."""
    import importlib.util

    from dgt_lib.exercises import RIGHT, grade

    path = Path(__file__).parents[1] / "notebooks" / "solutions" / "05_hybrid_astar.py"
    spec = importlib.util.spec_from_file_location("solutions_05", path)
    solution = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(solution)
    assert grade("edge_cost", solution.my_edge_cost).status == RIGHT
    cfg = PlannerConfig(heuristic="euclidean")
    library = _hill_planner(cfg=cfg).plan(*UP)
    plugged = _hill_planner(cfg=cfg, edge_cost=solution.my_edge_cost).plan(*UP)
    assert same_plan(library, plugged)
