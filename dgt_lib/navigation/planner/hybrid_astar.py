"""The Hybrid A* planner of one map (:class:`HybridAStar`): checks a query and runs its
search, the compiled one (:mod:`.compiled_search`) or the reference (:mod:`.search`)."""

from __future__ import annotations

import math
import time

import numpy as np

from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.constraints import check_section
from dgt_lib.core.geometry import GridSpec, wrap_angle
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.navigation.planner.compiled_search import CompiledSearch
from dgt_lib.navigation.planner.maps import PlannerMaps, Query
from dgt_lib.navigation.planner.result import InvalidQueryError, PlanResult
from dgt_lib.navigation.planner.search import EdgeCost, Search
from dgt_lib.navigation.planner.validation import check_maps

BLOCKING_CELLS = {1: "occupied cells (steeper than τ_s: a slope, a step or a tree)",
                  2: "unobserved cells (terrain the BEV map did not see)"}
"""How a rejected query names the occupancy values that block it."""

BACKENDS: tuple[str, ...] = ("compiled", "python")
"""The ways :class:`HybridAStar` can run its search (all return the same plans)."""


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
        (``tests/test_planner_exact.py``). ``"compiled"`` (default): the search loop
        compiled by numba (:mod:`.compiled`), several times faster per query
        (``benchmarks/bench_planner.py --backends compiled,python``); ``"python"``: the
        reference search (:class:`.search.Search`) in plain Python. Both read the same
        maps and the same compiled 2D cost-to-go.
    edge_cost: a function (length s [m], looked-up cost C, β) → g_edge [m] that replaces
        the paper's s(1 + C(1 + βC)) (:func:`.primitives.step_cost`) for primitives and
        shots; the reference search runs it (the heuristic keeps the paper's cost). None:
        the paper's, on the chosen backend.

    Attributes: ``maps`` (:class:`.maps.PlannerMaps`, what both searches read),
    ``blocked`` (H, W) the cells a footprint circle may not occupy, ``clearance_m``.
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
        edge_cost: EdgeCost | None = None,
    ):
        cfg = PlannerConfig() if cfg is None else cfg
        check_section(cfg, "planner")  # the one table of rules, for a planner made in code too
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        self.backend = backend
        self.edge_cost = edge_cost
        costmap, occupancy = np.asarray(costmap), np.asarray(occupancy)
        if costmap.ndim == 2:
            costmap = costmap[None]
        check_maps(costmap, occupancy, grid)
        if not min_turn_radius_m > 0:
            raise ValueError(f"min_turn_radius_m must be > 0, got {min_turn_radius_m}")
        self.cfg = cfg
        self.grid = grid
        self.maps = PlannerMaps(costmap, occupancy, grid, min_turn_radius_m=min_turn_radius_m,
                                footprint=footprint, cfg=cfg)
        self.blocked = self.maps.blocked.blocked
        self.clearance_m = self.maps.blocked.clearance_m

    @classmethod
    def for_vehicle(cls, costmap: np.ndarray, occupancy: np.ndarray, grid: GridSpec,
                    spec: VehicleSpec, cfg: PlannerConfig | None = None,
                    backend: str = "compiled", edge_cost: EdgeCost | None = None
                    ) -> HybridAStar:
        """The planner of one vehicle: its centre turning radius [m] and its footprint
        (length × width [m]) from its spec."""
        return cls(costmap, occupancy, grid, min_turn_radius_m=spec.centre_turn_radius_m,
                   footprint=(spec.length_m, spec.width_m), cfg=cfg, backend=backend,
                   edge_cost=edge_cost)

    def collides(self, poses: np.ndarray) -> np.ndarray:
        """(N,) bool: whether the footprint at each pose (N, 3) hits an occupied or
        unobserved cell or leaves the map (footprint circles, see the package docs)."""
        return self.maps.blocked.collides(poses)

    def cost_to_go(self, goal_xy) -> np.ndarray:
        """(H, W) admissible lower bound [cost units, i.e. metres of g_edge] of the cost
        from any pose in a cell to the goal region (∞ where the goal is unreachable);
        the bound: :class:`~dgt_lib.navigation.planner.heuristics.CostToGo`."""
        return self.maps.cost_to_go.field(goal_xy)

    # --- query -------------------------------------------------------------------------------

    def _check_query(self, start, goal) -> Query:
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
                f"{self.maps.footprint[0]:.2f}×{self.maps.footprint[1]:.2f} m footprint hits "
                f"{self._what_blocks(start)}"
            )
        r, c = self.grid.xy_to_cell(gx, gy)
        if self.maps.blocked.occupied_distance[r, c] == 0:
            raise InvalidQueryError(
                f"goal ({gx:.2f}, {gy:.2f}) is in an obstacle: on "
                f"{BLOCKING_CELLS[int(self.maps.occupancy[r, c])]}"
            )
        if gth is not None and self.collides((gx, gy, gth))[0]:
            raise InvalidQueryError(
                f"goal pose ({gx:.2f}, {gy:.2f}, {gth:.2f}) is in an obstacle: the footprint "
                f"hits {self._what_blocks((gx, gy, gth))}"
            )
        return Query(float(sx), float(sy), float(wrap_angle(sth)), float(gx), float(gy), gth)

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
        for off in self.maps.circle_offsets:
            px, py = x + off * math.cos(th), y + off * math.sin(th)
            if not self.grid.contains(px, py):
                found.append("the map edge")
                continue
            r, c = (int(v) for v in self.grid.xy_to_cell(px, py))
            rows, cols = np.mgrid[max(r - n, 0):min(r + n + 1, h), max(c - n, 0):min(c + n + 1, w)]
            near = np.hypot(rows - r, cols - c) * res < self.clearance_m
            values = np.unique(self.maps.occupancy[rows, cols][near])
            found += [BLOCKING_CELLS[int(v)] for v in values if v in BLOCKING_CELLS]
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
        cell, or a goal pose whose footprint collides. A goal not reached returns
        ``success=False`` and says why in ``failure``: ``"no_path"`` when no path exists
        (every pose the search can reach was expanded, or the 2D relaxation refutes the
        goal; ``reason`` starts "no path exists"), ``"budget"`` when ``max_expansions`` or
        ``max_time_s`` stopped the search first (``reason`` starts "search budget
        exhausted" and names the setting to raise).
        """
        t0 = time.perf_counter()
        query = self._check_query(start, goal)
        if self.backend == "compiled" and self.edge_cost is None:
            result = CompiledSearch(self.maps, query).run(t0)
            if result is not None:
                return result
            # a turn count beyond the compiled search's tables: the reference search
        return self._search(query).run(t0)

    def search(self, start, goal) -> Search:
        """The reference search of one query (:class:`.search.Search`), not yet started:
        to step through (``push_start()``, then ``steps()``) or to ``run``. Raises
        :class:`InvalidQueryError` as :meth:`plan` does."""
        return self._search(self._check_query(start, goal))

    def _search(self, query: Query) -> Search:
        if self.edge_cost is None:
            return Search(self.maps, query)
        return Search(self.maps, query, self.edge_cost)

