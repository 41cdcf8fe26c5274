"""The Hybrid A* planner: map set-up (:class:`HybridAStar`) and one query's search."""

from __future__ import annotations

import heapq
import itertools
import math
import time

import numpy as np

from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.geometry import TWO_PI, GridSpec, angle_diff, wrap_angle
from dgt_lib.core.vehicles import VehicleSpec, footprint_circles, get_vehicle
from dgt_lib.navigation.planner.collision import BlockedMap
from dgt_lib.navigation.planner.compiled_search import _CompiledSearch
from dgt_lib.navigation.planner.heuristics import (
    CostToGo,
    euclidean,
)
from dgt_lib.navigation.planner.primitives import (
    TURN_STEPS,
    PrimitiveSet,
    amplified_cost,
    distance,
    edge_cost,
    travel_bin_table,
)
from dgt_lib.navigation.planner.result import (
    SHOT,
    InvalidQueryError,
    Node,
    PlanResult,
    failure,
    success,
)
from dgt_lib.navigation.planner.shots import shot_cost, shot_poses
from dgt_lib.navigation.planner.validation import check_config, check_maps

BLOCKING_CELLS = {1: "occupied cells (steeper than τ_s: a slope, a step or a tree)",
                  2: "unobserved cells (terrain the BEV map did not see)"}
"""How a rejected query names the occupancy values that block it."""

BACKENDS: tuple[str, ...] = ("compiled", "python")
"""The ways :class:`HybridAStar` can run its search (all return the same plans)."""

heappush = heapq.heappush
_new_node = tuple.__new__  # _new_node(Node, fields): Node(*fields) at a plain tuple's cost


class HybridAStar:
    """Hybrid A* on one costmap + occupancy map for one vehicle.

    costmap: (K, H, W) float in [0, 1], layer k = heading 2πk/K (a (H, W) array
        is taken as K = 1, i.e. isotropic; zeros give a binary planner).
    occupancy: (H, W) uint8, 0 free, 1 occupied, 2 unobserved (= occupied).
    grid: the :class:`GridSpec` of both arrays.
    min_turn_radius_m: r_min [m] of the arc primitives.
    footprint: (length_m, width_m) of the vehicle rectangle centred on the pose.
    cfg: :class:`PlannerConfig` (step_m, beta, heuristic, tolerances, caps, ...).
    backend: how the search runs, one of :data:`BACKENDS`; both return the same plans
        (``tests/test_planner_exact.py``). ``"compiled"`` (default): the search loop and
        the 2D cost-to-go's Dijkstra compiled by numba (:mod:`.compiled`), 5–20× faster per
        query (``benchmarks/bench_planner.py --backends compiled,python``);
        ``"python"``: the reference search, plain Python (and scipy's Dijkstra).
    """

    def __init__(
        self,
        costmap: np.ndarray,
        occupancy: np.ndarray,
        grid: GridSpec,
        *,
        min_turn_radius_m: float,
        footprint: tuple[float, float],
        cfg: PlannerConfig | None = None,
        backend: str = "compiled",
    ):
        cfg = PlannerConfig() if cfg is None else cfg
        check_config(cfg)
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        if backend == "compiled":
            try:
                import numba  # noqa: F401
            except ImportError as exc:
                raise ImportError(
                    "HybridAStar(backend='compiled') needs numba, a dependency of dgt-kit "
                    "(pip install numba); backend='python' runs without it") from exc
        self.backend = backend
        costmap, occupancy = np.asarray(costmap), np.asarray(occupancy)
        if costmap.ndim == 2:
            costmap = costmap[None]
        check_maps(costmap, occupancy, grid)
        if not min_turn_radius_m > 0:
            raise ValueError(f"min_turn_radius_m must be > 0, got {min_turn_radius_m}")

        self.cfg = cfg
        self.grid = grid
        self.n_headings = costmap.shape[0]
        self.min_turn_radius_m = float(min_turn_radius_m)
        self.footprint = (float(footprint[0]), float(footprint[1]))
        self.circle_offsets, self.circle_radius_m = footprint_circles(*self.footprint)
        self._costmap = np.ascontiguousarray(costmap, dtype=np.float64)
        self._cost_flat = self._costmap.ravel()

        self._blocked = BlockedMap(
            occupancy, grid, self.circle_offsets, self.circle_radius_m,
            cfg.safety_margin_m, reach_m=cfg.step_m + float(np.abs(self.circle_offsets).max()),
            substeps=math.ceil(cfg.step_m / cfg.substep_m),
        )
        self.blocked = self._blocked.blocked  # (H, W) cells a footprint circle may not occupy
        self.clearance_m = self._blocked.clearance_m
        # distance [m] from every cell centre to the nearest occupied/unobserved cell centre
        self._occupied_distance = self._blocked.occupied_distance
        self._occupancy = occupancy  # to say what a rejected start or goal hits
        self._bin_table, self._bin_reach = travel_bin_table(
            cfg.step_m, grid.resolution, self.n_headings)
        self._cost_to_go = CostToGo(
            self._costmap, self.blocked, self._occupied_distance, grid, cfg,
            clearance_m=self.clearance_m, min_turn_radius_m=self.min_turn_radius_m,
            substep_m=self._substep(), compiled=backend == "compiled",
        )
        self._cost_to_go_cache = self._cost_to_go.cache  # the cost-to-go of recent goals
        self._compiled: tuple[np.ndarray, ...] | None = None

    @classmethod
    def for_vehicle(cls, costmap: np.ndarray, occupancy: np.ndarray, grid: GridSpec,
                    vehicle: str | VehicleSpec, cfg: PlannerConfig | None = None,
                    backend: str = "compiled") -> HybridAStar:
        """The planner of one vehicle: its centre turning radius and its footprint
        (length × width) from :mod:`dgt_lib.core.vehicles`."""
        spec = get_vehicle(vehicle)
        return cls(costmap, occupancy, grid, min_turn_radius_m=spec.centre_turn_radius_m,
                   footprint=(spec.length_m, spec.width_m), cfg=cfg, backend=backend)

    def _compiled_maps(self) -> tuple[np.ndarray, ...]:
        """The per-map arrays of :func:`.compiled.search` (built once): the padded blocked
        map, the flat costmap and the travel-direction layer table."""
        if self._compiled is None:
            self._compiled = (self._blocked.flat, self._cost_flat,
                              np.asarray(self._bin_table, dtype=np.int64))
        return self._compiled

    # --- collision -------------------------------------------------------------------------

    def collides(self, poses: np.ndarray) -> np.ndarray:
        """(N,) bool: whether the footprint at each pose (N, 3) hits an occupied or
        unobserved cell or leaves the map (footprint circles, see the package docs)."""
        return self._blocked.collides(poses)

    # --- heuristic -------------------------------------------------------------------------

    def cost_to_go(self, goal_xy) -> np.ndarray:
        """(H, W) admissible lower bound [cost units, i.e. metres of g_edge] of the cost
        from any pose in a cell to the goal region (∞ where the goal is unreachable);
        the bound and its proof: :class:`~dgt_lib.navigation.planner.heuristics.CostToGo`."""
        return self._cost_to_go.field(goal_xy)

    def _substep(self) -> float:
        """Actual sub-step spacing Δ [m] along a primitive (≤ cfg.substep_m)."""
        return self.cfg.step_m / math.ceil(self.cfg.step_m / self.cfg.substep_m)

    # --- query -------------------------------------------------------------------------------

    def _check_query(self, start, goal) -> tuple[float, float, float, float, float, float | None]:
        start = np.asarray(start, dtype=np.float64).ravel()
        goal = np.asarray(goal, dtype=np.float64).ravel()
        if start.shape != (3,) or not np.all(np.isfinite(start)):
            raise InvalidQueryError(f"start must be a finite (x, y, θ), got {start.tolist()}")
        if goal.shape not in ((2,), (3,)) or not np.all(np.isfinite(goal)):
            raise InvalidQueryError(
                f"goal must be a finite (x, y) or (x, y, θ), got {goal.tolist()}"
            )
        sx, sy, sth = start
        gx, gy = goal[:2]
        gth = float(goal[2]) if goal.shape == (3,) else None
        for name, (x, y) in (("start", (sx, sy)), ("goal", (gx, gy))):
            if not self.grid.contains(x, y):
                raise InvalidQueryError(
                    f"{name} ({x:.2f}, {y:.2f}) m is off the map (extent {self.grid.extent})"
                )
        if self.collides(start)[0]:
            raise InvalidQueryError(
                f"start pose ({sx:.2f}, {sy:.2f}, {sth:.2f}) is in an obstacle: the "
                f"{self.footprint[0]:.2f}×{self.footprint[1]:.2f} m footprint hits "
                f"{self._what_blocks(start)}"
            )
        r, c = self.grid.xy_to_cell(gx, gy)
        if self._occupied_distance[r, c] == 0:
            raise InvalidQueryError(
                f"goal ({gx:.2f}, {gy:.2f}) is in an obstacle: on "
                f"{BLOCKING_CELLS[int(self._occupancy[r, c])]}"
            )
        if gth is not None and self.collides((gx, gy, gth))[0]:
            raise InvalidQueryError(
                f"goal pose ({gx:.2f}, {gy:.2f}, {gth:.2f}) is in an obstacle: the footprint "
                f"hits {self._what_blocks((gx, gy, gth))}"
            )
        return float(sx), float(sy), float(wrap_angle(sth)), float(gx), float(gy), gth

    def check_query(self, start, goal) -> None:
        """Raise :class:`InvalidQueryError` where :meth:`plan` would, without searching:
        a start or goal off the map, a start pose whose footprint collides, a goal point
        in an occupied or unobserved cell, a goal pose whose footprint collides."""
        self._check_query(start, goal)

    def _what_blocks(self, pose) -> str:
        """What the footprint at ``pose`` (x, y, θ) collides with, in words: occupied
        and/or unobserved cells within the clearance of its circles, or the map edge."""
        x, y, th = (float(v) for v in pose)
        res, (h, w) = self.grid.resolution, self.grid.shape
        n = math.ceil(self.clearance_m / res) + 1
        found = []
        for off in self.circle_offsets:
            px, py = x + off * math.cos(th), y + off * math.sin(th)
            if not self.grid.contains(px, py):
                found.append("the map edge")
                continue
            r, c = (int(v) for v in self.grid.xy_to_cell(px, py))
            rows, cols = np.mgrid[max(r - n, 0):min(r + n + 1, h), max(c - n, 0):min(c + n + 1, w)]
            near = np.hypot(rows - r, cols - c) * res < self.clearance_m
            found += [BLOCKING_CELLS[int(v)] for v in np.unique(self._occupancy[rows, cols][near])
                      if v in BLOCKING_CELLS]
        return " and ".join(sorted(set(found))) or "an occupied or unobserved cell"

    def plan(self, start, goal) -> PlanResult:
        """Plan from ``start`` (x, y, θ) to ``goal`` (x, y) or (x, y, θ) [m, m, rad].

        The goal is reached when a node lies within ``goal_tolerance_m`` (and, if a
        goal heading is given, within ``goal_heading_tolerance_rad`` of it), or by an
        analytic shot (Dubins to a goal pose, turn-then-straight to a point) that is
        collision-free; a shot enters the open list as a goal candidate priced like
        primitives, so it is only taken when nothing cheaper is pending.

        Raises :class:`InvalidQueryError` for a start or goal off the map, a start
        pose whose footprint collides, a goal point in an occupied or unobserved
        cell, or a goal pose whose footprint collides. An unreachable goal returns
        ``success=False`` with a reason starting "no path", bounded by
        ``max_expansions`` and ``max_time_s``.
        """
        t0 = time.perf_counter()
        query = self._check_query(start, goal)
        if self.backend == "compiled":
            result = _CompiledSearch(self, *query).run(t0)
            if result is not None:
                return result
            # a turn count beyond the compiled search's tables: the reference search
        return self._plan_python(query, t0)

    def _plan_python(self, query, t0: float) -> PlanResult:
        """The reference search (``backend="python"``)."""
        search = _Search(self, *query)
        if not search.push_start():
            return failure("no path: the goal is unreachable even in the 2D relaxation", [], t0)
        max_expansions, max_time_s = self.cfg.max_expansions, self.cfg.max_time_s
        open_list, closed, expanded = search.open_list, search.closed, search.expanded
        perf_counter, heappop = time.perf_counter, heapq.heappop
        while open_list:
            if len(expanded) >= max_expansions:
                return failure(f"no path within max_expansions={max_expansions}", expanded, t0)
            if perf_counter() - t0 > max_time_s:
                return failure(f"no path within max_time_s={max_time_s}", expanded, t0)
            node = heappop(open_list)[2]
            if node.is_goal:
                return success(node, search.primitives, expanded, t0)
            if node.key in closed:
                continue
            closed.add(node.key)
            expanded.append((node.x, node.y))
            search.try_shot(node)
            search.expand(node)
        return failure("no path: every reachable pose was expanded (open list exhausted)",
                       expanded, t0)


class _Search:
    """One query's A* search: its state and its steps.

    State: the open list of (f, tie-break count, :class:`Node`), the closed set of
    (x, y, θ) cells, the best g into each cell and the best g of any goal node.
    f = g + w·h over the nodes' exact poses; the closed set keeps the first node
    expanded in each ``closed_cell_m`` × ``closed_cell_m`` × 360°/``theta_bins``
    cell (Hybrid A*'s state merging). Ties break by insertion order.
    """

    def __init__(self, planner: HybridAStar, sx: float, sy: float, sth: float,
                 gx: float, gy: float, gth: float | None):
        cfg = planner.cfg
        self.planner = planner
        self.start = (sx, sy)
        self.gx, self.gy, self.gth = gx, gy, gth
        self.tol2 = cfg.goal_tolerance_m * cfg.goal_tolerance_m
        self.heading_tol = cfg.goal_heading_tolerance_rad
        self.primitives = PrimitiveSet(
            sth, step_m=cfg.step_m, min_turn_radius_m=planner.min_turn_radius_m,
            substep_m=cfg.substep_m, circle_offsets=planner.circle_offsets,
            resolution=planner.grid.resolution, theta_bins=cfg.theta_bins,
            n_headings=planner.n_headings,
        )
        self.h_grid = self.h_terrain = None  # flat (H·W) lists of the 2D bounds
        if cfg.heuristic == "cost_to_go":
            self.h_grid, self.h_terrain = planner._cost_to_go.bounds((gx, gy), as_lists=True)
        self.weight = cfg.heuristic_weight
        self.shot_range2 = cfg.shot_distance_m**2 if cfg.analytic_shot else -1.0
        # the constants of the per-successor steps, bound once (the search's hot loop)
        self.step_m, self.beta = cfg.step_m, cfg.beta
        self.closed_cell_m, self.theta_bins = cfg.closed_cell_m, cfg.theta_bins
        self.x0, self.y0 = planner.grid.origin_xy
        self.H, self.W = planner.grid.shape
        self.inv_res = 1.0 / planner.grid.resolution
        self.nx_closed = math.ceil(self.W * planner.grid.resolution / cfg.closed_cell_m) + 1
        self.bin_table, self.reach = planner._bin_table, planner._bin_reach
        self.cost_flat = planner._cost_flat
        self.primitive_hits = planner._blocked.primitive_hits
        self.open_list: list[tuple[float, int, Node]] = []
        self.counter = itertools.count()
        self.closed: set[int] = set()
        self.best_g: dict[int, float] = {}
        self.best_goal = math.inf
        self.expanded: list[tuple[float, float]] = []

    def _closed_key(self, x: float, y: float, theta_bin: int) -> int:
        """The closed-set cell of a pose at (x, y) in heading bin ``theta_bin``."""
        cell = self.closed_cell_m
        kx = int((x - self.x0) / cell)
        ky = int((y - self.y0) / cell)
        return (ky * self.nx_closed + kx) * self.theta_bins + theta_bin

    def _is_goal(self, x: float, y: float, n: int) -> bool:
        """Whether a pose (x, y, θ_start + n·Δθ) lies in the goal region."""
        if (x - self.gx) ** 2 + (y - self.gy) ** 2 > self.tol2:
            return False
        if self.gth is None:
            return True
        heading = self.primitives.heading(n)
        return abs(float(angle_diff(heading, self.gth))) <= self.heading_tol

    def _heuristic(self, x: float, y: float, flat: int) -> float:
        """h at (x, y) in flat cell ``flat``: Euclidean, or its max with the 2D bound."""
        h = euclidean(x, y, self.gx, self.gy)
        if self.h_grid is not None:
            h = max(self.h_grid[flat], h + self.h_terrain[flat])
        return h

    def _push(self, node: Node, f: float) -> None:
        heapq.heappush(self.open_list, (f, next(self.counter), node))

    def push_start(self) -> bool:
        """Open the start node; False when the 2D bound already refutes the goal."""
        sx, sy = self.start
        row, col = self.planner.grid.xy_to_cell(sx, sy)
        row, col = int(row), int(col)
        flat = row * self.W + col
        if self.h_grid is not None and not math.isfinite(self.h_grid[flat]):
            return False
        sth = self.primitives.start_heading
        theta_bin = int(math.floor(sth / (TWO_PI / self.theta_bins) + 0.5)) % self.theta_bins
        key = self._closed_key(sx, sy, theta_bin)
        node = Node(sx, sy, 0, row, col, 0.0, None, -1, self._is_goal(sx, sy, 0), key)
        self.best_g[key] = 0.0
        self._push(node, self.weight * self._heuristic(sx, sy, flat))
        return True

    def try_shot(self, node: Node) -> None:
        """Open the goal reached by a collision-free analytic shot from ``node``, when
        it is within ``shot_distance_m`` and the shot beats the best goal so far."""
        x, y, g = node.x, node.y, node.g
        gx, gy = self.gx, self.gy
        if (x - gx) ** 2 + (y - gy) ** 2 > self.shot_range2:
            return
        if g + distance(x - gx, y - gy) >= self.best_goal:
            return
        planner = self.planner
        pose = (x, y, self.primitives.heading(node.turns))
        poses = shot_poses(pose, (gx, gy), self.gth, planner.min_turn_radius_m,
                           planner._substep(), self.best_goal - g)
        if poses is None or len(poses) == 0 or planner.collides(poses).any():
            return
        g_goal = g + shot_cost(pose, poses, planner.grid, self.cost_flat, planner.n_headings,
                               self.step_m, self.beta)
        if g_goal < self.best_goal:
            self.best_goal = g_goal
            self._push(Node(gx, gy, node.turns, -1, -1, g_goal, node, SHOT, True, -1, poses),
                       g_goal)

    def expand(self, node: Node) -> None:
        """Open the successors of ``node`` along the three arc primitives that are
        collision-free, in no closed cell, and cheaper than both the best known way
        into their closed cell and the best goal so far.

        The search's hot loop: :meth:`_closed_key`, :meth:`_heuristic` and
        :meth:`_push` are inlined here, and nodes are built without NamedTuple's
        Python-level constructor.
        """
        x, y, n, r0, c0, g = node[:6]
        cells, ends, closed_bins, fallback = self.primitives.table(n)
        hit = self.primitive_hits(x, y, cells)
        closed, best_g, open_list, counter = self.closed, self.best_g, self.open_list, self.counter
        s, beta, cell, n_bins = self.step_m, self.beta, self.closed_cell_m, self.theta_bins
        x0, y0, inv_res, nx_closed, H, W = (self.x0, self.y0, self.inv_res, self.nx_closed,
                                            self.H, self.W)
        gx, gy, h_grid, h_terrain = self.gx, self.gy, self.h_grid, self.h_terrain
        bin_table, reach, cost_flat = self.bin_table, self.reach, self.cost_flat
        bin_row = 2 * reach + 1
        for j in range(3):
            if hit[j]:
                continue
            dx, dy = ends[j]
            xn, yn = x + dx, y + dy
            key = ((int((yn - y0) / cell) * nx_closed + int((xn - x0) / cell)) * n_bins
                   + closed_bins[j])
            if key in closed:
                continue
            # directional cost lookup: layer k* of the cell move, else of the arc's heading
            rn = int((yn - y0) * inv_res)
            cn = int((xn - x0) * inv_res)
            k = bin_table[(rn - r0 + reach) * bin_row + (cn - c0 + reach)]
            if k < 0:
                k = fallback[j]
            cost = cost_flat[(k * H + rn) * W + cn]
            gn = g + edge_cost(s, amplified_cost(float(cost), beta))
            if gn >= best_g.get(key, math.inf) or gn >= self.best_goal:
                continue
            nn = n + TURN_STEPS[j]
            goal = self._is_goal(xn, yn, nn)
            if goal:
                hn = 0.0
            else:
                hn = distance(xn - gx, yn - gy)
                if h_grid is not None:
                    flat = rn * W + cn
                    hn = max(h_grid[flat], hn + h_terrain[flat])
                    if hn == math.inf:
                        continue
            best_g[key] = gn
            if goal:
                self.best_goal = gn  # < the previous best_goal, checked above
            successor = _new_node(Node, (xn, yn, nn, rn, cn, gn, node, j, goal, key, None))
            heappush(open_list, (gn + self.weight * hn, next(counter), successor))


def plan(
    start,
    goal,
    costmap: np.ndarray,
    occupancy: np.ndarray,
    grid: GridSpec,
    *,
    min_turn_radius_m: float,
    footprint: tuple[float, float],
    cfg: PlannerConfig | None = None,
    backend: str = "compiled",
) -> PlanResult:
    """One query: ``HybridAStar(costmap, occupancy, grid, ...).plan(start, goal)``.

    start (x, y, θ), goal (x, y) or (x, y, θ) [m, m, rad]; costmap (K, H, W) in
    [0, 1]; occupancy (H, W) uint8; footprint (length_m, width_m). See
    :class:`HybridAStar`. For several queries on one map, build the planner once.
    """
    planner = HybridAStar(costmap, occupancy, grid, min_turn_radius_m=min_turn_radius_m,
                          footprint=footprint, cfg=cfg, backend=backend)
    return planner.plan(start, goal)
