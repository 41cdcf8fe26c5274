"""The reference Hybrid A* search of one query, one step at a time (``backend="python"``).

Each step of :meth:`Search.steps` is one expansion, as in PythonRobotics' Hybrid A*:

1. pop the open node of least f = g + w·h (:meth:`Search.pop`); a goal node ends the
   search, a node whose closed-set cell is already closed is skipped;
2. close its cell and try an analytic shot to the goal (:meth:`Search.try_shot`);
3. expand the three arc primitives (:meth:`Search.expand`): each is checked for
   collisions along its sub-steps, priced at its end cell in the costmap layer k* of
   its cell move (the directional cost lookup) as g_edge = s(1 + C(1 + βC)), and pushed
   if it is cheaper than the best known way into its closed-set cell.

:mod:`.compiled` runs the very same steps as machine code; both return the same plans to
the bit (``tests/test_planner_exact.py``).
"""

from __future__ import annotations

import heapq
import itertools
import math
import time
from collections.abc import Callable, Iterator
from typing import NamedTuple

from dgt_lib.core.geometry import TWO_PI, angle_diff
from dgt_lib.navigation.planner.heuristics import euclidean
from dgt_lib.navigation.planner.maps import PlannerMaps, Query
from dgt_lib.navigation.planner.primitives import TURN_STEPS, distance, step_cost
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
from dgt_lib.navigation.planner.shots import SHOT_DISTANCE_M, shot_cost, shot_poses

EdgeCost = Callable[[float, float, float], float]
"""g_edge [m] of a move: (length s [m], looked-up cost C, β) → s(1 + C(1 + βC))."""

# what became of one primitive at an expansion (Expansion.outcomes)
PUSHED, COLLIDES, CLOSED, NOT_CHEAPER, UNREACHABLE = (
    "pushed", "collides", "closed", "not cheaper", "unreachable")


class Priced(NamedTuple):
    """One primitive of an expansion: its end (x, y) [m] and cell, the layer k* read,
    the looked-up cost C there, g and f of the successor (None where it was not priced)
    and its ``outcome`` (:data:`PUSHED`, :data:`COLLIDES`, :data:`CLOSED`,
    :data:`NOT_CHEAPER` or :data:`UNREACHABLE`)."""

    primitive: int
    x: float
    y: float
    row: int | None
    col: int | None
    layer: int | None
    cost: float | None
    g: float | None
    f: float | None
    outcome: str


class Expansion(NamedTuple):
    """One step of the search: the node popped and expanded, the analytic shot it opened
    (None if none) and its three primitives (:class:`Priced`)."""

    node: Node
    shot: Node | None
    primitives: list[Priced]


class Search:
    """One query's A* search: the open list of (f, insertion count, :class:`Node`), the
    closed set of (x, y, θ) cells, the best g into each cell and the best g of any goal.

    f = g + w·h over the nodes' exact poses; the closed set keeps the first node expanded
    in each ``closed_cell_m`` × ``closed_cell_m`` × 360°/``theta_bins`` cell (Hybrid A*'s
    state merging). Ties break by insertion order. ``edge_cost`` prices a move (default
    :func:`.primitives.step_cost`, the paper's).
    """

    def __init__(self, maps: PlannerMaps, query: Query, edge_cost: EdgeCost = step_cost):
        cfg = maps.cfg
        self.maps, self.cfg, self.query = maps, cfg, query
        self.edge_cost = edge_cost
        self.primitives = maps.primitives(query.sth)
        self.h_full = self.h_terrain = None  # the 2D bounds (H, W) of the cost-to-go
        if cfg.heuristic == "cost_to_go":
            self.h_full, self.h_terrain = maps.cost_to_go.bounds((query.gx, query.gy))
        self.nx_closed = math.ceil(maps.grid.shape[1] * maps.grid.resolution
                                   / cfg.closed_cell_m) + 1
        self.open_list: list[tuple[float, int, Node]] = []
        self.counter = itertools.count()
        self.closed: set[int] = set()
        self.best_g: dict[int, float] = {}
        self.best_goal = math.inf
        self.expanded: list[tuple[float, float]] = []
        self.goal: Node | None = None  # the goal node, once popped

    # --- the pieces of one step ---------------------------------------------------------

    def closed_key(self, x: float, y: float, theta_bin: int) -> int:
        """The closed-set cell of a pose at (x, y) [m] in heading bin ``theta_bin``."""
        x0, y0 = self.maps.grid.origin_xy
        cell = self.cfg.closed_cell_m
        return (int((y - y0) / cell) * self.nx_closed + int((x - x0) / cell)) \
            * self.cfg.theta_bins + theta_bin

    def is_goal(self, x: float, y: float, turns: int) -> bool:
        """Whether the pose (x, y, θ_start + turns·Δθ) lies in the goal region."""
        q = self.query
        tol = self.cfg.goal_tolerance_m
        if (x - q.gx) ** 2 + (y - q.gy) ** 2 > tol * tol:
            return False
        if q.gth is None:
            return True
        heading = self.primitives.heading(turns)
        return abs(float(angle_diff(heading, q.gth))) <= self.cfg.goal_heading_tolerance_rad

    def heuristic(self, x: float, y: float, row: int, col: int) -> float:
        """h at (x, y) in cell (row, col): Euclidean, or its max with the 2D bound."""
        h = euclidean(x, y, self.query.gx, self.query.gy)
        if self.h_full is not None:
            h = max(float(self.h_full[row, col]), h + float(self.h_terrain[row, col]))
        return h

    def push(self, node: Node, f: float) -> None:
        """Open ``node`` with priority f."""
        heapq.heappush(self.open_list, (f, next(self.counter), node))

    def pop(self) -> Node:
        """Take the open node of least f (first pushed among equals)."""
        return heapq.heappop(self.open_list)[2]

    def push_start(self) -> bool:
        """Open the start node; False when the 2D bound already refutes the goal."""
        q = self.query
        row, col = (int(v) for v in self.maps.grid.xy_to_cell(q.sx, q.sy))
        if self.h_full is not None and not math.isfinite(self.h_full[row, col]):
            return False
        n_bins = self.cfg.theta_bins
        theta_bin = int(math.floor(q.sth / (TWO_PI / n_bins) + 0.5)) % n_bins
        key = self.closed_key(q.sx, q.sy, theta_bin)
        self.best_g[key] = 0.0
        start = Node(q.sx, q.sy, 0, row, col, 0.0, None, -1, self.is_goal(q.sx, q.sy, 0), key)
        self.push(start, self.cfg.heuristic_weight * self.heuristic(q.sx, q.sy, row, col))
        return True

    def try_shot(self, node: Node) -> Node | None:
        """Open (and return) the goal reached by a collision-free analytic shot from
        ``node``, when it is within :data:`~dgt_lib.navigation.planner.shots.SHOT_DISTANCE_M`
        and beats the best goal so far."""
        q, cfg, maps = self.query, self.cfg, self.maps
        reach2 = SHOT_DISTANCE_M**2 if cfg.analytic_shot else -1.0
        if (node.x - q.gx) ** 2 + (node.y - q.gy) ** 2 > reach2:
            return None
        if node.g + distance(node.x - q.gx, node.y - q.gy) >= self.best_goal:
            return None
        pose = (node.x, node.y, self.primitives.heading(node.turns))
        poses = shot_poses(pose, (q.gx, q.gy), q.gth, maps.min_turn_radius_m,
                           maps.substep_m, self.best_goal - node.g)
        if poses is None or len(poses) == 0 or maps.blocked.collides(poses).any():
            return None
        g_goal = node.g + shot_cost(pose, poses, maps.grid, maps.cost_flat, maps.n_headings,
                                    cfg.step_m, cfg.beta, self.edge_cost)
        if g_goal >= self.best_goal:
            return None
        self.best_goal = g_goal
        goal = Node(q.gx, q.gy, node.turns, -1, -1, g_goal, node, SHOT, True, -1, poses)
        self.push(goal, g_goal)
        return goal

    def expand(self, node: Node) -> list[Priced]:
        """Price the three arc primitives from ``node`` and open the successors that are
        collision-free, in no closed cell and cheaper than both the best known way into
        their closed cell and the best goal so far."""
        table = self.primitives.table(node.turns)
        hits = self.maps.blocked.primitive_hits(node.x, node.y, table.cells)
        return [self.price(node, j, table.closed_bins[j], hits[j]) for j in range(3)]

    def price(self, node: Node, j: int, theta_bin: int, hit: bool) -> Priced:
        """Primitive j from ``node`` (``hit``: its footprint collides; ``theta_bin``: the
        closed-set heading bin of its end): the directional cost lookup, g, h, the push."""
        cfg = self.cfg
        end = self.primitives.successor(node.x, node.y, node.turns, node.row, node.col, j)
        if hit:
            return Priced(j, end.x, end.y, None, None, None, None, None, None, COLLIDES)
        key = self.closed_key(end.x, end.y, theta_bin)
        if key in self.closed:
            return Priced(j, end.x, end.y, None, None, None, None, None, None, CLOSED)
        cost = float(self.maps.costmap[end.layer, end.row, end.col])  # C in layer k*
        g = node.g + self.edge_cost(cfg.step_m, cost, cfg.beta)
        priced = (j, end.x, end.y, end.row, end.col, end.layer, cost, g)
        if g >= self.best_g.get(key, math.inf) or g >= self.best_goal:
            return Priced(*priced, None, NOT_CHEAPER)
        turns = node.turns + TURN_STEPS[j]
        is_goal = self.is_goal(end.x, end.y, turns)
        h = 0.0 if is_goal else self.heuristic(end.x, end.y, end.row, end.col)
        if h == math.inf:
            return Priced(*priced, None, UNREACHABLE)
        self.best_g[key] = g
        if is_goal:
            self.best_goal = g  # < the previous best_goal, checked above
        f = g + cfg.heuristic_weight * h
        self.push(Node(end.x, end.y, turns, end.row, end.col, g, node, j, is_goal, key), f)
        return Priced(*priced, f, PUSHED)

    # --- the loop -------------------------------------------------------------------------

    def steps(self) -> Iterator[Expansion]:
        """Expand nodes until a goal node is popped (then :attr:`goal` holds it) or the
        open list is empty, yielding each expansion (call :meth:`push_start` first)."""
        while self.open_list:
            node = self.pop()
            if node.is_goal:
                self.goal = node
                return
            if node.key in self.closed:
                continue
            self.closed.add(node.key)
            self.expanded.append((node.x, node.y))
            shot = self.try_shot(node)
            yield Expansion(node, shot, self.expand(node))

    def run(self, t0: float) -> PlanResult:
        """The query's :class:`PlanResult`, bounded by ``max_expansions`` and
        ``max_time_s`` (counted from ``t0``, a ``time.perf_counter()``): a failure is
        :data:`.result.NO_PATH` when the open list empties (or the 2D bound refutes the
        goal), :data:`.result.BUDGET` when a limit stops the search with nodes still open."""
        if not self.push_start():
            return no_path(UNREACHABLE_2D, [], t0)
        cfg = self.cfg
        if time.perf_counter() - t0 > cfg.max_time_s:
            return budget_exhausted("max_time_s", cfg.max_time_s, self.expanded, t0)
        for _ in self.steps():  # the limits stop a search with nodes left to pop
            if self.open_list and len(self.expanded) >= cfg.max_expansions:
                return budget_exhausted("max_expansions", cfg.max_expansions, self.expanded,
                                        t0)
            if self.open_list and time.perf_counter() - t0 > cfg.max_time_s:
                return budget_exhausted("max_time_s", cfg.max_time_s, self.expanded, t0)
        if self.goal is not None:
            return success(self.goal, self.primitives, self.expanded, t0)
        return no_path(OPEN_LIST_EMPTY, self.expanded, t0)
