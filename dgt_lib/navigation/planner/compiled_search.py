"""The compiled backend's driver: sets up the named arrays of :func:`.compiled.search` for one
query on a :class:`~.maps.PlannerMaps`, runs its numba loop (pausing to check the time
limit, growing its node arrays) and turns the result into the same
:class:`~.result.PlanResult` the reference search (:mod:`.search`) returns."""

from __future__ import annotations

import math
import time

import numpy as np

from dgt_lib.core.geometry import TWO_PI, angle_diff
from dgt_lib.navigation.planner.maps import PlannerMaps, Query
from dgt_lib.navigation.planner.primitives import distance
from dgt_lib.navigation.planner.result import (
    OPEN_LIST_EMPTY,
    SHOT,
    UNREACHABLE_2D,
    Node,
    PlanResult,
    budget_exhausted,
    no_path,
    success,
)
from dgt_lib.navigation.planner.shots import SHOT_DISTANCE_M, shot_poses


class CompiledSearch:
    """One query's search by :func:`.compiled.search`: the steps of :class:`.search.Search`
    on arrays (nodes, open list, closed set, turn tables), run in chunks of :attr:`CHUNK`
    expansions so that ``max_time_s`` is checked between them."""

    CHUNK = 4096  # expansions between two checks of max_time_s (a few ms)
    TURNS = 1024  # turn tables for turn counts −TURNS … TURNS (a path turns < 2π per 23)
    CAPACITY = 1 << 15  # nodes the arrays hold at first (doubled when full)

    def __init__(self, maps: PlannerMaps, query: Query):
        from dgt_lib.navigation.planner import compiled

        self.kernel = compiled
        self.maps, self.cfg, self.query = maps, maps.cfg, query
        self.primitives = maps.primitives(query.sth)
        self.params = self._params()
        H, W = maps.grid.shape
        res, cell = maps.grid.resolution, self.cfg.closed_cell_m
        self.n_keys = (math.ceil(H * res / cell) + 1) * self.params.nx_closed \
            * self.cfg.theta_bins

    def _params(self):
        """The query's :class:`.compiled.SearchParams`."""
        maps, cfg, q, grid = self.maps, self.cfg, self.query, self.maps.grid
        (H, W), res = grid.shape, grid.resolution
        blocked = maps.blocked
        return self.kernel.SearchParams(
            H=int(H), W=int(W), K=int(maps.n_headings), x0=float(grid.origin_xy[0]),
            y0=float(grid.origin_xy[1]), res=float(res), inv_res=1.0 / res,
            nx_closed=math.ceil(W * res / cfg.closed_cell_m) + 1,
            closed_cell=float(cfg.closed_cell_m), theta_bins=int(cfg.theta_bins),
            reach=int(maps.bin_reach), pad_width=int(blocked.padded_shape[1]),
            pad=int(blocked.pad), origin_row=float(blocked.cell_origin[0]),
            origin_col=float(blocked.cell_origin[1]),
            n_substeps=len(self.primitives.sub_t), n_circles=len(maps.circle_offsets),
            step=float(cfg.step_m), radius=maps.min_turn_radius_m, substep=maps.substep_m,
            start_heading=float(q.sth), dtheta=float(self.primitives.dtheta),
            turn_offset=int(self.TURNS), gx=float(q.gx), gy=float(q.gy),
            gth=0.0 if q.gth is None else float(q.gth), has_goal_heading=q.gth is not None,
            tol2=float(cfg.goal_tolerance_m * cfg.goal_tolerance_m),
            heading_tol=float(cfg.goal_heading_tolerance_rad), beta=float(cfg.beta),
            weight=float(cfg.heuristic_weight), use_cost_to_go=cfg.heuristic == "cost_to_go",
            shot_range2=float(SHOT_DISTANCE_M**2 if cfg.analytic_shot else -1.0),
            max_expansions=int(cfg.max_expansions))

    def _relaxations(self):
        """The goal's compiled Dijkstra runs, or (without the cost-to-go heuristic) the
        map's part of them, which the search then never reads."""
        if self.params.use_cost_to_go:
            return self.maps.cost_to_go.runs((self.query.gx, self.query.gy))
        return self.maps.cost_to_go._runs_template()[0]

    def _start(self, h):
        """The start node, as :meth:`.search.Search.push_start` makes it: (its f, key,
        row, col, whether it is a goal), or None when the 2D bound refutes the goal."""
        q, p = self.query, self.params
        row, col = (int(v) for v in self.maps.grid.xy_to_cell(q.sx, q.sy))
        estimate = distance(q.sx - q.gx, q.sy - q.gy)
        if p.use_cost_to_go:
            from dgt_lib.navigation.planner.compiled_dijkstra import bound_of, settle_cell

            settle_cell(row * p.W + col, h)
            h_full, h_terrain = bound_of(row * p.W + col, h.full.dist, h.terrain.dist,
                                         h.zero_terrain, h.phi)
            if not math.isfinite(h_full):
                return None
            estimate = max(h_full, estimate + h_terrain)
        theta_bin = int(math.floor(q.sth / (TWO_PI / p.theta_bins) + 0.5)) % p.theta_bins
        key = ((int((q.sy - p.y0) / p.closed_cell) * p.nx_closed
                + int((q.sx - p.x0) / p.closed_cell)) * p.theta_bins + theta_bin)
        is_goal = (q.sx - q.gx) ** 2 + (q.sy - q.gy) ** 2 <= p.tol2 and (
            q.gth is None or abs(float(angle_diff(q.sth, q.gth))) <= p.heading_tol)
        return p.weight * estimate, key, row, col, is_goal

    def _arrays(self, start):
        """The node, open-list, closed-set, progress and turn-table arrays, the start node
        in them."""
        c, p = self.kernel, self.params
        capacity = min(1 + 4 * self.cfg.max_expansions, self.CAPACITY)
        nodes = c.NodeArrays(*(np.empty(capacity) for _ in range(3)),
                             *(np.empty(capacity, np.int64) for _ in range(6)),
                             np.empty(capacity, np.bool_))
        f, key, row, col, is_goal = start
        for arr, value in zip(nodes, (self.query.sx, self.query.sy, 0.0, 0, row, col, -1, -1,
                                      key, is_goal), strict=True):
            arr[0] = value
        open_list = c.OpenList(np.empty(capacity), np.empty(capacity, np.int64),
                               np.empty(capacity, np.int64))
        open_list.f[0], open_list.count[0], open_list.node[0] = f, 0, 0
        closed = c.ClosedSet(np.zeros(self.n_keys, dtype=np.uint8), np.empty(self.n_keys))
        closed.state[key], closed.best_g[key] = 1, 0.0
        one = [np.zeros(1, np.int64) for _ in range(5)]
        progress = c.Progress(np.empty(capacity, np.int64), *one, np.array([math.inf]))
        progress.n_nodes[0] = progress.heap_size[0] = progress.counter[0] = 1
        n_tables, m = 2 * self.TURNS + 1, p.n_substeps * p.n_circles
        tables = c.TurnTables(self.maps.circle_offsets, self.primitives.sub_t,
                              np.zeros(n_tables, dtype=np.bool_), np.empty((n_tables, 3, m)),
                              np.empty((n_tables, 3, m)), np.empty((n_tables, 3, 2)),
                              np.empty((n_tables, 3), np.int64),
                              np.empty((n_tables, 3), np.int64))
        return nodes, open_list, closed, progress, tables

    def run(self, t0: float) -> PlanResult | None:
        """The query's result, its failure told apart as :meth:`.search.Search.run` does
        (CAPPED or the time limit: the budget; EXHAUSTED: no path), or None when a turn
        count left the tables (then the reference search must answer)."""
        c, cfg = self.kernel, self.cfg
        # numba compiles the kernels (or loads them from its cache) on their first call in
        # a process: that time does not count against max_time_s (it does in time_s)
        compiling, t_setup = not c.search.signatures, time.perf_counter()
        h = self._relaxations()
        start = self._start(h)
        if start is None:
            return no_path(UNREACHABLE_2D, [], t0)
        nodes, open_list, closed, progress, tables = self._arrays(start)
        maps = self.maps.compiled
        stop_at = 0  # max_time_s is checked first before the first expansion, as Search does
        t_limit = t0  # the clock of max_time_s
        while True:
            status = c.search(self.params, maps, h, tables, nodes, open_list, closed,
                              progress, stop_at)
            if compiling:
                t_limit, compiling = t0 + (time.perf_counter() - t_setup), False
            if status == c.NEED_ROOM:
                capacity = 2 * len(nodes.x)
                nodes = c.NodeArrays(*(np.resize(a, capacity) for a in nodes))
                open_list = c.OpenList(*(np.resize(a, capacity) for a in open_list))
                progress = progress._replace(expanded=np.resize(progress.expanded, capacity))
                continue
            if status == c.PAUSED:
                if time.perf_counter() - t_limit > cfg.max_time_s:
                    return budget_exhausted("max_time_s", cfg.max_time_s,
                                            self._expanded_xy(nodes, progress), t0)
                stop_at += self.CHUNK
                continue
            break
        done = self._expanded_xy(nodes, progress)
        if status == c.FOUND:
            goal = self._chain(nodes, int(progress.result[0]))
            return success(goal, self.primitives, done, t0)
        if status == c.CAPPED:
            return budget_exhausted("max_expansions", cfg.max_expansions, done, t0)
        if status == c.EXHAUSTED:
            return no_path(OPEN_LIST_EMPTY, done, t0)
        return None  # OUT_OF_TABLES

    @staticmethod
    def _expanded_xy(nodes, progress) -> np.ndarray:
        ids = progress.expanded[:progress.n_expanded[0]]
        return np.column_stack([nodes.x[ids], nodes.y[ids]])

    def _chain(self, nodes, goal: int) -> Node:
        """The goal's :class:`Node`, linked to its ancestors (the shot's poses rebuilt)."""
        ids = []
        i = goal
        while i >= 0:
            ids.append(i)
            i = int(nodes.parent[i])
        node = None
        for i in reversed(ids):
            shot = None
            if nodes.primitive[i] == SHOT:
                pose = (node.x, node.y, self.primitives.heading(node.turns))
                shot = shot_poses(pose, (self.query.gx, self.query.gy), self.query.gth,
                                  self.maps.min_turn_radius_m, self.maps.substep_m, math.inf)
            node = Node(float(nodes.x[i]), float(nodes.y[i]), int(nodes.turns[i]),
                        int(nodes.row[i]), int(nodes.col[i]), float(nodes.g[i]), node,
                        int(nodes.primitive[i]), bool(nodes.is_goal[i]), int(nodes.key[i]),
                        shot)
        return node
