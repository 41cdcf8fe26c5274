"""Start–goal queries of the three experiments, and which route a plan took
(paper: Experiments 1–3, Experimental Protocol).

Every method gets the same queries: Experiment 1 alternates ascents and descents of the
hill, Experiment 2 crossings of the ridge both ways, Experiment 3 random start–goal pairs
on the evaluation world. Queries are drawn from a seed, never from a method's result.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dgt_lib.core.config import ExperimentsConfig
from dgt_lib.core.geometry import wrap_angle
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


def hill_queries(world: World, n: int, cfg: ExperimentsConfig, seed: int) -> list[Query]:
    """n queries alternating ascent (base → summit) and descent (summit → base).

    Ascents start facing north-east, between Route A (east) and Route B (north), so
    the start heading favours neither; descents start facing south-east likewise.
    """
    rng = np.random.default_rng(seed)
    base, summit = world.landmarks["base"], world.landmarks["summit"]
    out = []
    for i in range(n):
        if i % 2 == 0:
            out.append(Query((*_jitter(rng, base, cfg.start_jitter_m),
                              _heading(rng, np.pi / 4, cfg.heading_jitter_deg)),
                             _jitter(rng, summit, cfg.start_jitter_m), "ascent"))
        else:
            out.append(Query((*_jitter(rng, summit, cfg.start_jitter_m),
                              _heading(rng, -np.pi / 4, cfg.heading_jitter_deg)),
                             _jitter(rng, base, cfg.start_jitter_m), "descent"))
    return out


def ridge_queries(world: World, n: int, cfg: ExperimentsConfig, seed: int) -> list[Query]:
    """n queries alternating south → north and north → south across the ridge."""
    rng = np.random.default_rng(seed)
    south, north = world.landmarks["south"], world.landmarks["north"]
    out = []
    for i in range(n):
        a, b, yaw, label = ((south, north, np.pi / 2, "northbound") if i % 2 == 0
                            else (north, south, -np.pi / 2, "southbound"))
        out.append(Query((*_jitter(rng, a, cfg.start_jitter_m),
                          _heading(rng, yaw, cfg.heading_jitter_deg)),
                         _jitter(rng, b, cfg.start_jitter_m), label))
    return out


def random_queries(maps: WorldMaps, n: int, cfg: ExperimentsConfig, seed: int,
                   vehicle: str) -> list[Query]:
    """n random start–goal pairs on free cells of the occupancy map, their distance
    in ``cfg.eval_distance_m``, start heading uniform; both must be valid planner
    queries for ``vehicle`` (no footprint collision) — otherwise resampled."""
    rng = np.random.default_rng(seed)
    planner = HybridAStar.for_vehicle(binary_costmap(maps.grid.shape), maps.occupancy,
                                      maps.grid, vehicle)
    x0, x1, y0, y1 = maps.grid.extent
    lo, hi = cfg.eval_distance_m
    out: list[Query] = []
    for _ in range(200 * max(n, 1)):
        if len(out) == n:
            break
        sx, sy = rng.uniform(x0 + 10, x1 - 10), rng.uniform(y0 + 10, y1 - 10)
        ang, dist = rng.uniform(0, 2 * np.pi), rng.uniform(lo, hi)
        gx, gy = sx + dist * np.cos(ang), sy + dist * np.sin(ang)
        if not (x0 + 10 < gx < x1 - 10 and y0 + 10 < gy < y1 - 10):
            continue
        start = (float(sx), float(sy), float(rng.uniform(0, 2 * np.pi)))
        goal_poses = [(gx, gy, th) for th in np.linspace(0, 2 * np.pi, 8, endpoint=False)]
        if planner.collides(start)[0] or planner.collides(np.array(goal_poses)).all():
            continue
        out.append(Query(start, (float(gx), float(gy)), "random"))
    if len(out) < n:
        raise RuntimeError(f"found only {len(out)} of {n} valid random queries on {maps.world}")
    return out


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
