"""Start–goal queries of the three experiments, and which route a plan took
(paper: Experiments 1–3, Experimental Protocol).

Every method gets the same queries: Experiment 1 alternates ascents and descents of the
hill, Experiment 2 crossings of the ridge both ways, Experiment 3 random start–goal pairs
on the evaluation world — kept only where the straight line crosses terrain a vehicle
cannot cross (:mod:`dgt_lib.evaluation.hazards`) and Hybrid A* finds a kinematically
feasible path. Queries are drawn from a seed, never from a method's result.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dgt_lib.core.config import ExperimentsConfig, PlannerConfig
from dgt_lib.core.geometry import wrap_angle
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.evaluation.hazards import HazardMap
from dgt_lib.mapping.baselines import binary_costmap
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.navigation.planner import HybridAStar
from dgt_lib.world.worlds import World, polyline_distance


@dataclass(frozen=True)
class Query:
    """A start pose (x [m], y [m], yaw [rad]) and a goal (x, y) [m], with a label
    (e.g. "ascent"/"descent") shared by every method."""

    start: tuple[float, float, float]
    goal: tuple[float, float]
    label: str = ""


def _jitter(rng: np.random.Generator, xy, sigma_m: float) -> tuple[float, float]:
    d = rng.uniform(-sigma_m, sigma_m, 2)
    return float(xy[0] + d[0]), float(xy[1] + d[1])


def _heading(rng, base_rad: float, jitter_deg: float) -> float:
    return float(wrap_angle(base_rad + np.radians(rng.uniform(-jitter_deg, jitter_deg))))


def _back_and_forth(rng: np.random.Generator, n: int, cfg: ExperimentsConfig,
                    there: tuple, back: tuple) -> list[Query]:
    """n queries alternating ``there`` and ``back``, each (start, goal, start yaw [rad],
    label); the start and goal jittered by ``start_jitter_m``, the yaw by
    ``heading_jitter_deg``."""
    out = []
    for i in range(n):
        a, b, yaw, label = there if i % 2 == 0 else back
        out.append(Query((*_jitter(rng, a, cfg.start_jitter_m),
                          _heading(rng, yaw, cfg.heading_jitter_deg)),
                         _jitter(rng, b, cfg.start_jitter_m), label))
    return out


def hill_queries(world: World, n: int, cfg: ExperimentsConfig, seed: int) -> list[Query]:
    """n queries alternating ascent (base → summit) and descent (summit → base).

    Ascents start facing north-east, between Route A (east) and Route B (north), so
    the start heading favours neither; descents start facing south-east likewise.
    """
    base, summit = world.landmarks["base"], world.landmarks["summit"]
    return _back_and_forth(np.random.default_rng(seed), n, cfg,
                           (base, summit, np.pi / 4, "ascent"),
                           (summit, base, -np.pi / 4, "descent"))


def ridge_queries(world: World, n: int, cfg: ExperimentsConfig, seed: int) -> list[Query]:
    """n queries alternating south → north and north → south across the ridge."""
    south, north = world.landmarks["south"], world.landmarks["north"]
    return _back_and_forth(np.random.default_rng(seed), n, cfg,
                           (south, north, np.pi / 2, "northbound"),
                           (north, south, -np.pi / 2, "southbound"))


REJECTIONS: tuple[str, ...] = ("off_map", "footprint", "hazard", "infeasible")
"""Why :func:`draw_random_queries` rejected a candidate: the goal too near the map edge,
the start or goal footprint in an obstacle, too little hazardous terrain on the straight
segment, no kinematically feasible path."""


@dataclass(frozen=True)
class QueryDraw:
    """The outcome of :func:`draw_random_queries`: the queries kept, how many candidates
    were drawn, and how many were rejected for each of :data:`REJECTIONS`; ``tried`` is
    every candidate in the order drawn, as ``(start, goal, fate)`` with fate ``"kept"`` or
    a rejection (what a notebook plots)."""

    queries: list[Query]
    candidates: int
    rejected: dict[str, int]
    tried: list[tuple[tuple, tuple, str]] = field(default_factory=list, compare=False)

    def kept_by_hazard_rule(self) -> float:
        """Share of the candidates that reached the hazard rule (on the map, footprints
        free) which it kept."""
        reached = self.candidates - self.rejected["off_map"] - self.rejected["footprint"]
        return (reached - self.rejected["hazard"]) / reached if reached else float("nan")


def is_feasible(planner: HybridAStar, start, goal) -> bool:
    """Whether ``planner`` (Hybrid A*: the vehicle's turning radius and footprint on the
    occupancy map) finds a path from ``start`` (x, y, θ) to ``goal`` (x, y) [m, rad]. A
    goal unreachable even in 2D (the cost-to-go field is ∞ at the start) is rejected
    without a search."""
    r, c = planner.grid.xy_to_cell(start[0], start[1])
    if not np.isfinite(planner.cost_to_go(goal[:2])[r, c]):
        return False
    return planner.plan(start, goal).success


def draw_random_queries(maps: WorldMaps, n: int, cfg: ExperimentsConfig, seed: int,
                        vehicle: str, *, hazards: HazardMap | None = None,
                        planner_cfg: PlannerConfig | None = None,
                        margin_m: float = 10.0) -> QueryDraw:
    """n random start–goal pairs (Experiment 3) and what was rejected on the way.

    Candidates: a start uniform on the map at least ``margin_m`` from its edge, heading
    uniform, a goal at a distance uniform in ``cfg.eval_distance_m`` in a uniform
    direction (also ``margin_m`` inside the map). A candidate is kept when, in this order,

    1. the start footprint is free and some goal heading's footprint is (occupancy map);
    2. with ``hazards``, the straight segment start → goal crosses at least
       ``cfg.eval_min_hazard_m`` of hazard cells (:mod:`dgt_lib.evaluation.hazards`:
       computed from the true heights, never from a method);
    3. Hybrid A* with ``vehicle``'s turning radius and footprint finds a path on the
       occupancy map with a zero costmap (``planner_cfg``: the trials' planner settings)
       — a query no method could drive is not a test of the costmap.

    Otherwise it is resampled; after 200 × n candidates a ``RuntimeError`` says how many
    were found and why the others were rejected. Deterministic in ``seed``.
    """
    rng = np.random.default_rng(seed)
    planner = HybridAStar.for_vehicle(binary_costmap(maps.grid.shape), maps.occupancy,
                                      maps.grid, get_vehicle(vehicle),
                                      cfg=planner_cfg)
    x0, x1, y0, y1 = maps.grid.extent
    lo, hi = cfg.eval_distance_m
    out: list[Query] = []
    rejected = dict.fromkeys(REJECTIONS, 0)
    tried: list[tuple[tuple, tuple, str]] = []
    for _ in range(200 * max(n, 1)):
        if len(out) == n:
            break
        sx, sy = rng.uniform(x0 + margin_m, x1 - margin_m), rng.uniform(y0 + margin_m,
                                                                         y1 - margin_m)
        ang, dist = rng.uniform(0, 2 * np.pi), rng.uniform(lo, hi)
        gx, gy = sx + dist * np.cos(ang), sy + dist * np.sin(ang)
        start = (float(sx), float(sy), float(rng.uniform(0, 2 * np.pi)))
        goal = (float(gx), float(gy))
        goal_poses = [(gx, gy, th) for th in np.linspace(0, 2 * np.pi, 8, endpoint=False)]
        if not (x0 + margin_m < gx < x1 - margin_m and y0 + margin_m < gy < y1 - margin_m):
            fate = "off_map"
        elif planner.collides(start)[0] or planner.collides(np.array(goal_poses)).all():
            fate = "footprint"
        elif hazards is not None and hazards.length_m(start, goal) < cfg.eval_min_hazard_m:
            fate = "hazard"
        elif not is_feasible(planner, start, goal):
            fate = "infeasible"
        else:
            fate = "kept"
            out.append(Query(start, goal, "random"))
        if fate != "kept":
            rejected[fate] += 1
        tried.append((start, goal, fate))
    candidates = len(tried)
    if len(out) < n:
        raise RuntimeError(
            f"found only {len(out)} of {n} random queries for {vehicle} on {maps.world} in "
            f"{candidates} candidates; rejected: "
            + ", ".join(f"{k} {v}" for k, v in rejected.items())
            + " (ExperimentsConfig.eval_distance_m and eval_min_hazard_m set what is kept)")
    return QueryDraw(out, candidates, rejected, tried)


def random_queries(maps: WorldMaps, n: int, cfg: ExperimentsConfig, seed: int,
                   vehicle: str, *, hazards: HazardMap | None = None,
                   planner_cfg: PlannerConfig | None = None) -> list[Query]:
    """The queries of :func:`draw_random_queries`."""
    return draw_random_queries(maps, n, cfg, seed, vehicle, hazards=hazards,
                               planner_cfg=planner_cfg).queries


RIDGE_SMOOTH_HALF_WIDTH_M = 9.0
"""Half-width of the ridge's smoothed section around ``smooth_crossing`` [m] (worlds.make_ridge)."""


def classify_route(world: World, path: np.ndarray, tolerance_m: float = 6.0) -> str:
    """Which way a planned path went, "" for worlds without routes.

    Hill: the route whose polyline is closest on average ("A" or "B"), "other" when
    even that one is farther than ``tolerance_m`` on average. Ridge: where the path
    crosses the ridge line — "smooth" within the smoothed section, else "sharp" (the
    ridge is sharp everywhere else, across the whole map).
    """
    if len(path) == 0:
        return ""
    xy = np.asarray(path, dtype=float)[:, :2]
    if world.name == "hill":
        mean_d = {key: float(polyline_distance(xy, world.routes[key])[0].mean())
                  for key in ("A", "B")}
        best = min(mean_d, key=mean_d.get)
        return best if mean_d[best] <= tolerance_m else "other"
    if world.name == "ridge":
        y_ridge = world.landmarks["sharp_crossing"][1]
        x_cross = xy[int(np.argmin(np.abs(xy[:, 1] - y_ridge))), 0]
        smooth_x = world.landmarks["smooth_crossing"][0]
        return "smooth" if abs(x_cross - smooth_x) <= RIDGE_SMOOTH_HALF_WIDTH_M else "sharp"
    return ""
