"""The exact planner's costs do not move: recorded from the pure-Python search at commit
3adf92a (before the planner was made faster) on the deterministic queries of
``tests/planner_cases.py``; the compiled search (the default backend) must return the
reference search's plan on every one of them, node for node.

Hybrid A*'s closed set keeps the first node expanded in each (x, y, θ) cell, so a search
that pops nodes in another order may return another (slightly costlier or cheaper) path:
the cost is exact only up to that discretisation. A faster search that pops the same nodes
in the same order returns the same cost to rounding, which is what is asserted: the
recorded cost to 1e-9, relative. A heuristic that overestimates, a wrong edge cost, a
missed collision or a changed closed-set rule moves some of these costs far more.
"""

import dataclasses
import math

import numpy as np
import pytest
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.geometry import GridSpec
from dgt_lib.navigation.planner import BUDGET, NO_PATH, HybridAStar, PlanResult
from dgt_lib.navigation.planner.compiled_kernels import squared_distances
from dgt_lib.navigation.planner.heuristics import disk_minimum
from tests import planner_cases

RECORDED = {  # name: (cost, expansions) of the pure-Python search at commit 3adf92a
    "hill-up-cost_to_go": (79.09468236695092, 3092),
    "hill-down-cost_to_go": (49.968000000000025, 435),
    "hill-up-euclidean": (79.56400517657829, 6749),
    "hill-down-euclidean": (49.968000000000025, 749),
    "hill-up-isotropic": (79.09468236695092, 3092),
    "hill-up-noshot": (79.344, 3238),
    "field-0": (125.66461791217671, 362),
    "field-1": (235.8881376462216, 6606),
    "field-2": (228.09691041358047, 2768),
    "field-3": (186.4613357809515, 1730),
    "field-4": (105.82731680001736, 773),
    "field-5": (140.19387993435078, 1097),
    "field-6": (136.60338543726445, 528),
    "field-7": (354.1924583124266, 12456),
    "field-0-euclidean": (125.66461791217671, 471),
    "box-main": (123.91569911277193, 15182),
}

CASES = planner_cases.cases()


@pytest.fixture(scope="module")
def maps():
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = planner_cases.maps(name)
        return cache[name]

    return get


def test_every_case_is_recorded():
    assert sorted(name for name, *_ in CASES) == sorted(RECORDED)


def same_plan(a, b) -> bool:
    """Whether two PlanResults describe the same search: outcome (and which failure), path,
    nodes, node costs, and every expanded node in the same order."""
    return (a.success == b.success and a.failure == b.failure and a.reason == b.reason
            and a.expansions == b.expansions
            and a.cost == b.cost and np.array_equal(a.path, b.path)
            and np.array_equal(a.nodes, b.nodes) and np.array_equal(a.node_costs, b.node_costs)
            and np.array_equal(a.expanded_xy, b.expanded_xy))


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_exact_cost_is_the_recorded_one_and_both_backends_agree(maps, case):
    """The reference search returns the recorded cost; the compiled search expands the
    same nodes in the same order and returns the same plan, to the bit."""
    name, map_name, vehicle, cfg, start, goal = case
    cfg = dataclasses.replace(cfg, max_time_s=3600.0)  # the plan must not depend on load
    results = {}
    for backend in ("python", "compiled"):
        planner = HybridAStar(*maps(map_name), cfg=cfg, backend=backend, **vehicle)
        results[backend] = planner.plan(start, goal)
    ref = results["python"]
    cost, _ = RECORDED[name]
    assert ref.success and math.isfinite(ref.cost)
    assert ref.cost == pytest.approx(cost, rel=1e-9, abs=0.0)
    assert ref.node_costs[-1] == ref.cost
    assert same_plan(ref, results["compiled"])
    if cfg.heuristic == "cost_to_go":  # the compiled runs, taken on after the search
        cost_to_go = planner.maps.cost_to_go
        for ours, scipys in zip(cost_to_go.bounds(goal[:2]), scipy_bounds(cost_to_go, goal),
                                strict=True):
            np.testing.assert_array_equal(ours, scipys)


def scipy_bounds(cost_to_go, goal) -> tuple[np.ndarray, np.ndarray]:
    """(φ·D, φ·D_c) by scipy's Dijkstra on the two relaxations' reversed 8-connected graphs
    (edge v → u carries the cost of the move u → v, charged at v): the compiled runs'
    reference, built from the same per-map moves."""
    moves = cost_to_go._relaxation_moves()
    H, W = cost_to_go.grid.shape
    index = np.arange(H * W).reshape(H, W)
    rows, cols, terrain, lengths = [], [], [], []
    for m, ((dr, dc), length) in enumerate(zip(moves.steps, moves.lengths, strict=True)):
        least = moves.layers[moves.near[m]].min(axis=0)  # T_m
        u = (slice(max(0, -dr), H - max(0, dr)), slice(max(0, -dc), W - max(0, dc)))
        v = (slice(max(0, dr), H - max(0, -dr)), slice(max(0, dc), W - max(0, -dc)))
        ok = moves.passable[u] & moves.passable[v] & np.isfinite(least[v])
        rows.append(index[v][ok])
        cols.append(index[u][ok])
        terrain.append(length * least[v][ok])
        lengths.append(np.full(int(ok.sum()), length))
    pairs, terrain = (np.concatenate(rows), np.concatenate(cols)), np.concatenate(terrain)
    source = cost_to_go._goal_cells(*goal[:2])
    phi = cost_to_go.runs(goal[:2]).phi
    return tuple(phi * dijkstra(csr_matrix((w, pairs), shape=(H * W, H * W)), directed=True,
                                indices=source, min_only=True).reshape(H, W)
                 for w in (np.concatenate(lengths) + terrain, terrain))


def _hill_planners(occupancy=None, **cfg):
    costmap, hill_occupancy, grid = planner_cases.hill_maps()
    occupancy = hill_occupancy if occupancy is None else occupancy
    return [HybridAStar(costmap, occupancy, grid, cfg=PlannerConfig(**cfg), backend=b,
                        **planner_cases.HILL) for b in ("python", "compiled")]


UP = ((40.0, 8.0, math.pi / 2), (40.0, 52.0))


def _hill_occupancies():
    """The hill's occupancy as it is ("open"), with both gaps walled off ("closed"), and
    walled off with the start boxed into a 30 m × 25 m pen ("pen")."""
    _, occupancy, grid = planner_cases.hill_maps()
    X, Y = grid.cell_centers()
    closed = occupancy.copy()
    closed[(Y > 25.0) & (Y < 35.0)] = 1
    pen = closed.copy()
    pen[(Y < 25.0) & ((X < 25.0) | (X > 55.0))] = 1
    return {"open": occupancy, "closed": closed, "pen": pen}


PENNED = dict(heuristic="euclidean", closed_cell_m=1.6, theta_bins=36)
FAILURES = [  # occupancy, planner settings, failure, the reason's opening
    ("closed", {}, NO_PATH,
     "no path exists: the goal is unreachable even in the 2D relaxation"),
    ("pen", PENNED, NO_PATH, "no path exists: every pose the search can reach was expanded "
                             "(open list exhausted)"),
    ("closed", dict(heuristic="euclidean", max_expansions=500), BUDGET,
     "search budget exhausted after 500 expansions (planner.max_expansions=500): no path "
     "found yet, none ruled out; raise it, e.g. --set planner.max_expansions=1000"),
    ("open", dict(max_expansions=5), BUDGET,
     "search budget exhausted after 5 expansions (planner.max_expansions=5): no path found "
     "yet, none ruled out; raise it, e.g. --set planner.max_expansions=10"),
]


@pytest.mark.parametrize("occupancy,cfg,kind,reason", FAILURES,
                         ids=["refuted-in-2d", "boxed-in", "capped-walled-off", "capped-open"])
def test_failures_are_told_apart_and_the_same_in_both_backends(occupancy, cfg, kind, reason):
    """No path exists (refuted by the 2D relaxation; a start boxed in, whose open list
    empties) or the search budget ran out (a walled-off goal, or a reachable one, with
    max_expansions tiny): both backends say which, in the same words, after the same
    expansions."""
    ref, fast = (p.plan(*UP) for p in _hill_planners(_hill_occupancies()[occupancy], **cfg))
    assert not ref.success and ref.failure == kind and ref.reason == reason
    assert ref.path.shape == (0, 3) and ref.cost == math.inf
    assert same_plan(ref, fast)


def test_the_boxed_in_start_ends_within_the_budget_and_the_open_goal_is_reachable():
    """The cases above differ in what they say, not in what they were given: the pen's
    search ends well before the default 200,000 expansions, and the open hill's query has
    a path."""
    occupancies = _hill_occupancies()
    pen = _hill_planners(occupancies["pen"], **PENNED)[1].plan(*UP)
    open_hill = _hill_planners(occupancies["open"])[1].plan(*UP)
    assert pen.failure == NO_PATH and pen.expansions < PlannerConfig().max_expansions
    assert open_hill.success and open_hill.failure == "" and open_hill.expansions > 5


def test_max_time_is_checked_before_the_first_expansion():
    for planner in _hill_planners(max_time_s=1e-9):
        result = planner.plan(*UP)
        assert not result.success and result.failure == BUDGET
        assert result.reason.startswith("search budget exhausted after 0 expansions in ")
        assert result.reason.endswith("(planner.max_time_s=1e-09): no path found yet, none "
                                      "ruled out; raise it, e.g. --set planner.max_time_s=2e-09")
        assert result.expansions == 0


def test_a_plan_result_s_failure_agrees_with_its_success():
    """``failure`` is "" exactly on success and one of the two kinds otherwise."""
    found = dict(path=np.zeros((1, 3)), cost=0.0, expansions=0, time_s=0.0, success=True,
                 reason="reached goal")
    assert PlanResult(**found).failure == ""
    for bad in (dict(found, failure=NO_PATH), dict(found, success=False),
                dict(found, success=False, failure="gave up")):
        with pytest.raises(ValueError, match="failure"):
            PlanResult(**bad)


def test_a_start_in_the_goal_region_is_the_whole_path():
    start = (40.0, 8.0, math.pi / 2)
    ref, fast = (p.plan(start, (40.3, 8.4)) for p in _hill_planners())
    assert ref.success and ref.expansions == 0 and len(ref.path) == 1
    assert same_plan(ref, fast)


@pytest.mark.parametrize("limits", [dict(CHUNK=7), dict(CAPACITY=8), dict(TURNS=2)],
                         ids=["time-checks", "growing-arrays", "turn-table-fallback"])
def test_compiled_bookkeeping_does_not_change_the_plan(monkeypatch, limits):
    """Pausing every 7 expansions (to check max_time_s), growing the node arrays from 8
    entries, or running out of turn tables (the reference search then answers) gives the
    reference plan."""
    from dgt_lib.navigation.planner.compiled_search import CompiledSearch

    for attr, value in limits.items():
        monkeypatch.setattr(CompiledSearch, attr, value)
    ref, fast = (p.plan(*UP) for p in _hill_planners())
    assert ref.success and same_plan(ref, fast)


def test_disk_minimum_is_scipys_minimum_filter():
    rng = np.random.default_rng(3)
    values = rng.random((37, 53))
    values[rng.random(values.shape) < 0.2] = np.inf
    for rho in (0.5, 1.0, 2.5, 5.5):
        half = math.floor(rho)
        d = np.arange(-half, half + 1)
        disk = np.hypot(d[:, None], d[None, :]) <= rho
        expected = ndimage.minimum_filter(values, footprint=disk, mode="constant",
                                          cval=np.inf)
        np.testing.assert_array_equal(disk_minimum(values, disk), expected)


def test_the_goal_s_cells_are_every_passable_cell_within_reach_of_it():
    """The runs start from the passable cells whose centre is within tolerance + res·√2/2
    of the goal, measured on a window around it: the same cells as over the whole map,
    at the map's corners and edges too."""
    planner = _hill_planners()[1]
    cost_to_go, grid = planner.maps.cost_to_go, planner.grid
    cost_to_go._relaxation_moves()
    reach = cost_to_go.cfg.goal_tolerance_m + grid.resolution * math.sqrt(2) / 2
    X, Y = grid.cell_centers()
    x0, x1, y0, y1 = grid.extent
    rng = np.random.default_rng(0)
    goals = [(x0, y0), (x1 - 1e-9, y1 - 1e-9), (x0 + 0.3, y1 - 0.2), *rng.uniform(
        (x0, y0), (x1, y1), (20, 2))]
    for gx, gy in goals:
        expected = np.flatnonzero((np.hypot(X - gx, Y - gy) <= reach)
                                  & ~cost_to_go.impassable)
        np.testing.assert_array_equal(cost_to_go._goal_cells(gx, gy), expected)


def test_the_compiled_distance_transform_is_scipys():
    rng = np.random.default_rng(5)
    for _ in range(60):
        shape = rng.integers(1, 50, 2)
        occupied = rng.random(shape) < rng.choice([0.002, 0.05, 0.5, 0.95])
        occupied.flat[rng.integers(occupied.size)] = True
        np.testing.assert_array_equal(np.sqrt(squared_distances(occupied)),
                                      ndimage.distance_transform_edt(~occupied))


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_a_map_without_obstacles_blocks_no_cell(backend):
    """No cell is near an obstacle where there is none (scipy's transform, given no
    obstacle, measures from a point beyond the map's corner)."""
    grid = GridSpec((0.0, 0.0), 0.5, (40, 60))
    planner = HybridAStar(np.zeros((8, *grid.shape)), np.zeros(grid.shape, np.uint8), grid,
                          min_turn_radius_m=4.0, footprint=(4.0, 2.0), backend=backend)
    assert not planner.blocked.any()
    assert planner.plan((2.5, 1.5, 0.0), (25.0, 1.5, 0.0)).success
