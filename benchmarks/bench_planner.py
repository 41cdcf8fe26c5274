"""Benchmark of ``dgt_lib.planner``: time and expansions per query on synthetic maps.

Three kinds of maps at 0.4 m, K = 8 (the first two 160 m × 160 m, 400 × 400 cells):

- ``hill``: a plateau 10 m up, reached by a short steep ramp (Route B, ~34°) in
  the middle or a long gentle ramp (Route A, ~11°) on the left; the rest of the
  plateau edge is a cliff (occupied). The directional cost is high for uphill
  travel on steep ground and low downhill, plus a smooth random texture and
  random trees. Queries go up (ascent) and down (descent) between random
  points below and on the plateau.
- ``random``: a smooth random directional cost in [0, 0.3] and random round
  obstacles; queries between random free points 60–150 m apart.
- ``world_hill``: ``dgt_lib.worlds.make_hill`` (Experiment 1, 140 m × 140 m)
  with the same slope-based cost computed from its true heights; ascents
  base → summit and descents summit → base (Route A ≈ 242 m, Route B ≈ 82 m).

Prints, per map kind and heuristic, the median / 90th-percentile time per query
(including the heuristic's per-goal set-up, excluding the per-map set-up, which
is printed separately) as wall time and as this process's CPU time (the fairer
figure on a shared, loaded machine), CPU µs per expansion, expansions, success
rate and path cost; for the hills, the route each direction took. Run::

    .venv/bin/python benchmarks/bench_planner.py            # 20 queries per map kind
    .venv/bin/python benchmarks/bench_planner.py --queries 5
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from scipy import ndimage

from dgt_lib.config import PlannerConfig
from dgt_lib.geometry import GridSpec, heading_bins
from dgt_lib.planner import HybridAStar

SIZE_M, RES_M, K = 160.0, 0.4, 8
CARLA_COLA = dict(min_turn_radius_m=5.71, footprint=(6.4, 2.4))  # dgt_lib.vehicles values


def directional_slope_cost(height: np.ndarray, res: float, rng: np.random.Generator) -> np.ndarray:
    """(K, H, W) cost in [0, 1]: a smooth texture, plus the uphill grade along θ_k
    squared (climbing), plus the cross grade squared (roll when driving across)."""
    gy, gx = np.gradient(height, res)  # rise per metre along y (rows) and x (columns)
    texture = ndimage.gaussian_filter(rng.random(height.shape), 6.0)
    texture = 0.02 + 0.08 * (texture - texture.min()) / (np.ptp(texture) + 1e-12)
    cost = []
    for th in heading_bins(K):
        grade = gx * np.cos(th) + gy * np.sin(th)
        cross = -gx * np.sin(th) + gy * np.cos(th)
        cost.append(texture + 2.0 * np.maximum(grade, 0.0) ** 2 + 1.0 * cross**2)
    return np.clip(np.stack(cost), 0.0, 1.0)


def hill_map(seed: int):
    """The hill map: (costmap, occupancy, grid, ramps) with ramps = {"A": x-range, "B": x-range}."""
    rng = np.random.default_rng(seed)
    n = int(SIZE_M / RES_M)
    grid = GridSpec((0.0, 0.0), RES_M, (n, n))
    X, Y = grid.cell_centers()
    top = 10.0
    height = np.zeros((n, n))
    plateau = Y >= 110.0
    height[plateau] = top
    ramp_b = (X >= 70.0) & (X <= 90.0) & (Y >= 95.0) & (Y < 110.0)  # 15 m for 10 m: steep
    height[ramp_b] = top * (Y[ramp_b] - 95.0) / 15.0
    ramp_a = (X >= 12.0) & (X <= 32.0) & (Y >= 60.0) & (Y < 110.0)  # 50 m for 10 m: gentle
    height[ramp_a] = top * (Y[ramp_a] - 60.0) / 50.0
    cost = directional_slope_cost(height, RES_M, rng)
    gy, gx = np.gradient(height, RES_M)
    cliff = np.hypot(gx, gy) > 1.0  # τ_s: steeper than 45° is occupied
    # the ramps' side walls are cliffs as well
    for x_lo, x_hi, y_lo in ((70.0, 90.0, 95.0), (12.0, 32.0, 60.0)):
        side = (Y >= y_lo) & (Y < 110.0) & ((np.abs(X - x_lo) < 0.6) | (np.abs(X - x_hi) < 0.6))
        cliff |= side
    edge = (np.abs(Y - 110.0) < 0.6) & ~((X > 70.0) & (X < 90.0)) & ~((X > 12.0) & (X < 32.0))
    occupancy = (cliff | edge).astype(np.uint8)
    trees = rng.random((n, n)) < 0.0004
    trees &= ~(ramp_a | ramp_b)
    occupancy[ndimage.binary_dilation(trees, iterations=2)] = 1
    return cost, occupancy, grid


def random_map(seed: int):
    """A random map: smooth directional cost in [0, 0.3], round obstacles (~6% of cells)."""
    rng = np.random.default_rng(seed)
    n = int(SIZE_M / RES_M)
    grid = GridSpec((0.0, 0.0), RES_M, (n, n))
    base = ndimage.gaussian_filter(rng.random((K, n, n)), (0.0, 8.0, 8.0))
    base = (base - base.min()) / (np.ptp(base) + 1e-12)
    cost = 0.3 * base**2
    X, Y = grid.cell_centers()
    occupancy = np.zeros((n, n), dtype=np.uint8)
    for _ in range(45):
        cx, cy = rng.uniform(0, SIZE_M, 2)
        radius = rng.uniform(1.0, 4.0)
        occupancy[np.hypot(X - cx, Y - cy) < radius] = 1
    return cost, occupancy, grid


def world_hill_map(seed: int):
    """``dgt_lib.worlds``' Experiment 1 hill (140 m × 140 m) with a ground-truth
    slope-based directional cost, occupancy = gradient > 1 (45°) or a tree."""
    from dgt_lib.worlds import make_hill

    world = make_hill(RES_M, seed)
    grid = world.grid
    heights = world.heights.astype(np.float64)
    cost = directional_slope_cost(heights, RES_M, np.random.default_rng(seed))
    gy, gx = np.gradient(heights, RES_M)
    occupancy = (np.hypot(gx, gy) > 1.0).astype(np.uint8)
    X, Y = grid.cell_centers()
    for x, y, radius, _ in world.trees:
        occupancy[np.hypot(X - x, Y - y) < radius + 0.2] = 1
    return cost, occupancy, grid, world


def world_hill_queries(world, rng: np.random.Generator, n: int):
    """Alternating ascents (base → summit) and descents, each end jittered by ≤ 2 m."""
    base, summit = np.array(world.landmarks["base"]), np.array(world.landmarks["summit"])
    queries = []
    for i in range(n):
        a, b = (base, summit) if i % 2 == 0 else (summit, base)
        start = a + rng.uniform(-2, 2, 2)
        goal = b + rng.uniform(-2, 2, 2)
        queries.append(((*start, np.pi / 2 if i % 2 == 0 else -np.pi / 2), tuple(goal)))
    return queries


def random_queries(planner: HybridAStar, rng: np.random.Generator, n: int, region=None):
    """n (start, goal) pairs, both collision-free, 60–150 m apart; region(x, y) -> (is_start)."""
    queries = []
    while len(queries) < n:
        s = np.append(rng.uniform(5, SIZE_M - 5, 2), rng.uniform(0, 2 * np.pi))
        g = rng.uniform(5, SIZE_M - 5, 2)
        if not 60.0 <= np.hypot(*(s[:2] - g)) <= 150.0:
            continue
        if region is not None and not region(s, g):
            continue
        gr, gc = planner.grid.xy_to_cell(*g)
        if planner.collides(s)[0] or planner.blocked[gr, gc]:
            continue
        queries.append((tuple(s), tuple(g)))
    return queries


def run(kind: str, heuristic: str, n_queries: int, seed: int, cfg: PlannerConfig) -> None:
    world = None
    if kind == "world_hill":
        cost, occupancy, grid, world = world_hill_map(seed)
    else:
        cost, occupancy, grid = (hill_map if kind == "hill" else random_map)(seed)
    cfg = dataclasses.replace(cfg, heuristic=heuristic)
    label = heuristic + ("" if cfg.heuristic_weight == 1 else f"×{cfg.heuristic_weight:g}")
    t = time.perf_counter()
    planner = HybridAStar(cost, occupancy, grid, cfg=cfg, **CARLA_COLA)
    if heuristic == "cost_to_go":
        planner.cost_to_go((80.0, 80.0))  # builds the per-map 2D cost field
        planner._cost_to_go_cache.clear()
    setup = time.perf_counter() - t
    rng = np.random.default_rng(seed + 1)
    if world is not None:
        queries = world_hill_queries(world, rng, n_queries)
    elif kind == "hill":
        def up_down(s, g):  # one end below the plateau, the other on it
            return min(s[1], g[1]) < 90.0 and max(s[1], g[1]) > 115.0
        queries = random_queries(planner, rng, n_queries, up_down)
    else:
        queries = random_queries(planner, rng, n_queries)
    times, cpu, expansions, costs, ok = [], [], [], [], 0
    routes = {"ascent": [], "descent": []}
    for start, goal in queries:
        t_cpu = time.process_time()
        result = planner.plan(start, goal)
        cpu.append(time.process_time() - t_cpu)
        times.append(result.time_s)
        expansions.append(result.expansions)
        if result.success:
            ok += 1
            costs.append(result.cost)
            direction = "ascent" if start[1] < goal[1] else "descent"
            if world is not None:  # B: through its steep section; A: round its corner
                xy = result.path[:, :2]
                lo, hi = world.landmarks["B_steep_bottom"], world.landmarks["B_steep_top"]
                on_b = np.any((np.abs(xy[:, 0] - lo[0]) < 6.0) & (xy[:, 1] > lo[1])
                              & (xy[:, 1] < hi[1]))
                on_a = np.any(np.hypot(*(xy - world.landmarks["A_corner"]).T) < 10.0)
                routes[direction].append("B" if on_b else "A" if on_a else "?")
            elif kind == "hill":
                on_edge = result.path[np.abs(result.path[:, 1] - 102.0) < 1.0]
                route = "B" if on_edge[:, 0].mean() > 50.0 else "A"
                routes[direction].append(route)
    times, cpu, expansions = np.array(times), np.array(cpu), np.array(expansions)
    median_cost = np.median(costs) if costs else np.nan
    print(
        f"{kind:10s} {label:14s} map set-up {setup:5.2f} s | per query: wall median "
        f"{np.median(times):6.3f} s, p90 {np.percentile(times, 90):6.3f} s | CPU median "
        f"{np.median(cpu):6.3f} s, p90 {np.percentile(cpu, 90):6.3f} s, max {cpu.max():6.3f} s"
        f" | {1e6 * cpu.sum() / max(expansions.sum(), 1):4.0f} µs CPU/expansion"
        f" | expansions median {int(np.median(expansions)):6d}, max {expansions.max():6d}"
        f" | success {ok}/{len(queries)} | median cost {median_cost:8.1f}"
    )
    if kind in ("hill", "world_hill"):
        for direction, taken in routes.items():
            print(f"        {direction}: routes {''.join(taken)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--queries", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--kinds", default="hill,random,world_hill",
                        help="hill (synthetic), random, world_hill (dgt_lib.worlds.make_hill)")
    parser.add_argument("--heuristics", default="cost_to_go,euclidean")
    parser.add_argument("--max-time", type=float, default=10.0)
    parser.add_argument("--weights", default="1.0", help="heuristic_weight values, comma-separated")
    parser.add_argument("--closed-cell", type=float, default=None, help="closed_cell_m override")
    parser.add_argument("--theta-bins", type=int, default=None, help="theta_bins override")
    args = parser.parse_args()
    cfg = PlannerConfig(max_time_s=args.max_time)
    if args.closed_cell is not None:
        cfg = dataclasses.replace(cfg, closed_cell_m=args.closed_cell)
    if args.theta_bins is not None:
        cfg = dataclasses.replace(cfg, theta_bins=args.theta_bins)
    print(f"PlannerConfig: {cfg}")
    for kind in args.kinds.split(","):
        for heuristic in args.heuristics.split(","):
            for weight in args.weights.split(","):
                run(kind, heuristic, args.queries, args.seed,
                    dataclasses.replace(cfg, heuristic_weight=float(weight)))


if __name__ == "__main__":
    main()
