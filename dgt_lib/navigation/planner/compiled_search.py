"""The compiled backend's driver: sets up :mod:`dgt_lib.navigation.planner.compiled`'s
arrays for one query of a :class:`~dgt_lib.navigation.planner.search.HybridAStar`, runs its
numba search loop (pausing to check the time limit, growing its node arrays) and turns the
result into the same :class:`~dgt_lib.navigation.planner.result.PlanResult` the Python
reference search returns."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

from dgt_lib.core.geometry import TWO_PI, angle_diff
from dgt_lib.navigation.planner.heuristics import (
    DijkstraRuns,
    step_cell_bounds,
)
from dgt_lib.navigation.planner.primitives import (
    PrimitiveSet,
    distance,
)
from dgt_lib.navigation.planner.result import (
    SHOT,
    Node,
    PlanResult,
    failure,
    success,
)
from dgt_lib.navigation.planner.shots import shot_poses

if TYPE_CHECKING:  # an annotation only: search imports this module
    from dgt_lib.navigation.planner.search import HybridAStar


class _CompiledSearch:
    """One query's search by :func:`.compiled.search`: the same steps as :class:`_Search`
    on arrays (nodes, open list, closed set, turn tables), run in chunks of
    :attr:`CHUNK` expansions so that ``max_time_s`` is checked between them."""

    CHUNK = 4096  # expansions between two checks of max_time_s (a few ms)
    TURNS = 1024  # turn tables for turn counts −TURNS … TURNS (a path turns < 2π per 23)
    CAPACITY = 1 << 15  # nodes the arrays hold at first (doubled when full)

    def __init__(self, planner: HybridAStar, sx: float, sy: float, sth: float,
                 gx: float, gy: float, gth: float | None):
        from dgt_lib.navigation.planner import compiled

        self.kernel = compiled
        cfg, grid = planner.cfg, planner.grid
        self.planner, self.cfg = planner, cfg
        self.start, self.goal, self.gth = (sx, sy, sth), (gx, gy), gth
        self.primitives = PrimitiveSet(
            sth, step_m=cfg.step_m, min_turn_radius_m=planner.min_turn_radius_m,
            substep_m=cfg.substep_m, circle_offsets=planner.circle_offsets,
            resolution=grid.resolution, theta_bins=cfg.theta_bins,
            n_headings=planner.n_headings,
        )
        H, W = grid.shape
        res = grid.resolution
        blocked = planner._blocked
        c = compiled
        ip = np.zeros(c.I_N_I, dtype=np.int64)
        ip[c.I_H], ip[c.I_W], ip[c.I_K] = H, W, planner.n_headings
        ip[c.I_NX_CLOSED] = math.ceil(W * res / cfg.closed_cell_m) + 1
        ip[c.I_BINS], ip[c.I_REACH] = cfg.theta_bins, planner._bin_reach
        ip[c.I_HAS_GTH] = gth is not None
        ip[c.I_USE_H] = cfg.heuristic == "cost_to_go"
        ip[c.I_PAD_W], ip[c.I_PAD] = blocked.padded_shape[1], blocked.pad
        ip[c.I_NSUB], ip[c.I_NCIRC] = len(self.primitives.sub_t), len(planner.circle_offsets)
        ip[c.I_MAX_EXP], ip[c.I_TURN_OFFSET] = cfg.max_expansions, self.TURNS
        fp = np.zeros(c.F_N_F)
        fp[c.F_X0], fp[c.F_Y0] = grid.origin_xy
        fp[c.F_INV_RES], fp[c.F_CELL], fp[c.F_RES] = 1.0 / res, cfg.closed_cell_m, res
        fp[c.F_GX], fp[c.F_GY], fp[c.F_GTH] = gx, gy, 0.0 if gth is None else gth
        fp[c.F_TOL2] = cfg.goal_tolerance_m * cfg.goal_tolerance_m
        fp[c.F_HEADING_TOL], fp[c.F_WEIGHT] = cfg.goal_heading_tolerance_rad, cfg.heuristic_weight
        fp[c.F_SHOT_RANGE2] = cfg.shot_distance_m**2 if cfg.analytic_shot else -1.0
        fp[c.F_STEP], fp[c.F_BETA] = cfg.step_m, cfg.beta
        fp[c.F_START_TH], fp[c.F_DTHETA] = sth, self.primitives.dtheta
        fp[c.F_RADIUS], fp[c.F_SUBSTEP] = planner.min_turn_radius_m, planner._substep()
        fp[c.F_ORIGIN_R], fp[c.F_ORIGIN_C] = blocked._origin
        fp[c.F_PHI] = cfg.step_m / step_cell_bounds(cfg.step_m, res)[0]
        self.ip, self.fp = ip, fp
        self.ny_closed = math.ceil(H * res / cfg.closed_cell_m) + 1

    def _heuristic_runs(self):
        """The goal's compiled Dijkstra runs (:class:`DijkstraRuns`), or 1-element dummies
        of the same types without the cost-to-go heuristic."""
        if self.cfg.heuristic == "cost_to_go":
            return self.planner._cost_to_go.runs(self.goal)
        return DijkstraRuns((np.zeros(1, np.bool_), np.zeros((1, 8)), None),
                            np.zeros((8, 2), np.int64), (1, 1), np.zeros(0, np.int64), 1.0)

    def run(self, t0: float) -> PlanResult | None:
        """The query's result, or None when a turn count left the tables (then the
        reference search must answer)."""
        c, cfg, planner = self.kernel, self.cfg, self.planner
        runs = self._heuristic_runs()
        self.ip[c.I_ZERO_TERRAIN] = runs.zero_terrain
        sx, sy, sth = self.start
        gx, gy = self.goal
        row, col = (int(v) for v in planner.grid.xy_to_cell(sx, sy))
        flat = row * planner.grid.shape[1] + col
        use_h = cfg.heuristic == "cost_to_go"
        if use_h:
            h_grid, h_terrain = runs.at(flat)
            if not math.isfinite(h_grid):
                return failure("no path: the goal is unreachable even in the 2D relaxation",
                               [], t0)
        # the start node, as _Search.push_start makes it
        n_bins = cfg.theta_bins
        theta_bin = int(math.floor(sth / (TWO_PI / n_bins) + 0.5)) % n_bins
        x0, y0 = planner.grid.origin_xy
        key = ((int((sy - y0) / cfg.closed_cell_m) * self.ip[c.I_NX_CLOSED]
                + int((sx - x0) / cfg.closed_cell_m)) * n_bins + theta_bin)
        h = distance(sx - gx, sy - gy)
        if use_h:
            h = max(h_grid, h + h_terrain)
        heading_tol = cfg.goal_heading_tolerance_rad
        start_is_goal = (sx - gx) ** 2 + (sy - gy) ** 2 <= self.fp[c.F_TOL2] and (
            self.gth is None or abs(float(angle_diff(sth, self.gth))) <= heading_tol)

        capacity = min(1 + 4 * cfg.max_expansions, self.CAPACITY)
        nodes = self._node_arrays(capacity)
        hf, hc, hnode = (np.empty(capacity), np.empty(capacity, np.int64),
                         np.empty(capacity, np.int64))
        nodes[0][0], nodes[1][0], nodes[2][0] = sx, sy, 0.0  # x, y, g
        for arr, value in zip(nodes[3:], (0, row, col, -1, -1, key, start_is_goal),
                              strict=True):
            arr[0] = value  # turns, row, col, parent, primitive, key, is_goal
        hf[0], hc[0], hnode[0] = cfg.heuristic_weight * h, 0, 0
        n_keys = self.ny_closed * self.ip[c.I_NX_CLOSED] * n_bins
        key_state = np.zeros(n_keys, dtype=np.uint8)
        best_g = np.empty(n_keys)
        key_state[key], best_g[key] = 1, 0.0
        expanded = np.empty(capacity, np.int64)
        state = np.zeros(c.S_N_S, dtype=np.int64)
        state[c.S_NODES], state[c.S_HEAP], state[c.S_COUNTER] = 1, 1, 1
        best_goal = np.array([math.inf])
        n_tables = 2 * self.TURNS + 1
        m = len(self.primitives.sub_t) * len(planner.circle_offsets)
        tables = (np.zeros(n_tables, dtype=np.bool_), np.empty((n_tables, 3, m)),
                  np.empty((n_tables, 3, m)), np.empty((n_tables, 3, 2)),
                  np.empty((n_tables, 3), np.int64), np.empty((n_tables, 3), np.int64))
        maps = planner._compiled_maps()
        stop_at = 0  # max_time_s is checked first before the first expansion, as _Search does
        while True:
            status = c.search(self.ip, self.fp, *maps, *runs.args,
                              planner.circle_offsets, self.primitives.sub_t, *tables, *nodes,
                              hf, hc, hnode, key_state, best_g, expanded, state, best_goal,
                              stop_at)
            if status == c.NEED_ROOM:
                capacity *= 2
                nodes = tuple(np.resize(a, capacity) for a in nodes)
                hf, hc, hnode, expanded = (np.resize(a, capacity)
                                           for a in (hf, hc, hnode, expanded))
                continue
            if status == c.PAUSED:
                if time.perf_counter() - t0 > cfg.max_time_s:
                    return failure(f"no path within max_time_s={cfg.max_time_s}",
                                   self._expanded_xy(nodes, expanded, state), t0)
                stop_at += self.CHUNK
                continue
            break
        done = self._expanded_xy(nodes, expanded, state)
        if status == c.FOUND:
            return success(self._chain(nodes, int(state[c.S_RESULT])), self.primitives, done, t0)
        if status == c.CAPPED:
            return failure(f"no path within max_expansions={cfg.max_expansions}", done, t0)
        if status == c.EXHAUSTED:
            return failure("no path: every reachable pose was expanded (open list exhausted)",
                           done, t0)
        return None  # OUT_OF_TABLES

    @staticmethod
    def _node_arrays(capacity: int) -> tuple[np.ndarray, ...]:
        """x, y, g, turns, row, col, parent, primitive, key, is_goal."""
        return (*(np.empty(capacity) for _ in range(3)),
                *(np.empty(capacity, np.int64) for _ in range(6)),
                np.empty(capacity, np.bool_))

    def _expanded_xy(self, nodes, expanded, state) -> np.ndarray:
        ids = expanded[:state[self.kernel.S_EXPANDED]]
        return np.column_stack([nodes[0][ids], nodes[1][ids]])

    def _chain(self, nodes, goal: int) -> Node:
        """The goal's :class:`Node`, linked to its ancestors (the shot's poses rebuilt)."""
        x, y, g, turns, row, col, parent, primitive, key, is_goal = nodes
        ids = []
        i = goal
        while i >= 0:
            ids.append(i)
            i = int(parent[i])
        node = None
        for i in reversed(ids):
            shot = None
            if primitive[i] == SHOT:
                pose = (node.x, node.y, self.primitives.heading(node.turns))
                shot = shot_poses(pose, self.goal, self.gth, self.planner.min_turn_radius_m,
                                  self.planner._substep(), math.inf)
            node = Node(float(x[i]), float(y[i]), int(turns[i]), int(row[i]), int(col[i]),
                        float(g[i]), node, int(primitive[i]), bool(is_goal[i]), int(key[i]),
                        shot)
        return node
