"""Benchmark of ``dgt_lib.navigation.planner``: time and expansions per query on synthetic maps.

Three kinds of maps at 0.4 m, K = 8 (the first two 160 m × 160 m, 400 × 400 cells):

- ``hill``: a plateau 10 m up, reached by a short steep ramp (Route B, ~34°) in
  the middle or a long gentle ramp (Route A, ~11°) on the left; the rest of the
  plateau edge is a cliff (occupied). The directional cost is high for uphill
  travel on steep ground and low downhill, plus a smooth random texture and
  random trees. Queries go up (ascent) and down (descent) between random
  points below and on the plateau.
- ``random``: a smooth random directional cost in [0, 0.3] and random round
  obstacles; queries between random free points 60–150 m apart.
- ``world_hill``: ``dgt_lib.world.worlds.make_hill`` (Experiment 1, 140 m × 140 m)
  with the same slope-based cost computed from its true heights; ascents
  base → summit and descents summit → base (Route A ≈ 242 m, Route B ≈ 82 m).

Prints, per map kind and heuristic, the median / 90th-percentile time per query
(including the heuristic's per-goal set-up, excluding the per-map set-up, which
is printed separately) as wall time and as this process's CPU time (the fairer
figure on a shared, loaded machine), CPU µs per expansion, expansions, success
rate and path cost; for the hills, the route each direction took. Run::

    .venv/bin/python benchmarks/bench_planner.py            # 20 queries per map kind
    .venv/bin/python benchmarks/bench_planner.py --queries 5
    # the compiled search and its plain-Python reference on the same queries (the plans
    # must be identical; the line after each pair says whether they were):
    .venv/bin/python benchmarks/bench_planner.py --backends compiled,python
    # the hill/ridge/eval experiments' own queries, every method, on the smoke profile's
    # cached costmaps ($DGT_DATA_DIR), or on the paper worlds' true-height costs:
    .venv/bin/python benchmarks/bench_planner.py --experiments smoke --queries 10
    .venv/bin/python benchmarks/bench_planner.py --experiments truth:paper --queries 10
    # time an older planner module against this one, same queries, interleaved:
    .venv/bin/python benchmarks/bench_planner.py --compare /tmp/planner_old.py --queries 6
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import importlib.util
import os
import sys
import time
import types

import numpy as np
from scipy import ndimage

from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.geometry import GridSpec, heading_bins
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.navigation.planner import HybridAStar

SIZE_M, RES_M, K = 160.0, 0.4, 8
CARLA_COLA = dict(min_turn_radius_m=5.71, footprint=(6.4, 2.4))  # dgt_lib.core.vehicles values


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
    """``dgt_lib.world.worlds``' Experiment 1 hill (140 m × 140 m) with a ground-truth
    slope-based directional cost, occupancy = gradient > 1 (45°) or a tree."""
    from dgt_lib.world.terrain import make_hill

    world = make_hill(RES_M, seed)
    return (*truth_maps(world, seed), world)


def truth_maps(world, seed: int):
    """(costmap, occupancy, grid) of a world from its true heights: the slope-based
    directional cost, occupancy = gradient > 1 (45°) or within 0.2 m of a trunk."""
    grid = world.grid
    heights = world.heights.astype(np.float64)
    cost = directional_slope_cost(heights, grid.resolution, np.random.default_rng(seed))
    gy, gx = np.gradient(heights, grid.resolution)
    occupancy = (np.hypot(gx, gy) > 1.0).astype(np.uint8)
    X, Y = grid.cell_centers()
    for x, y, radius, _ in world.trees:
        occupancy[np.hypot(X - x, Y - y) < radius + 0.2] = 1
    return cost, occupancy, grid


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


def make_map(kind: str, seed: int):
    """(costmap, occupancy, grid, world) of one map kind (world is None but for world_hill)."""
    if kind == "world_hill":
        return world_hill_map(seed)
    return (*(hill_map if kind == "hill" else random_map)(seed), None)


def make_planner(planner_cls, maps, cfg: PlannerConfig, **kwargs):
    """A planner of class ``planner_cls`` on ``maps`` with the per-map 2D cost field built
    (for ``cost_to_go``) and no goal cached; returns (planner, set-up time [s])."""
    cost, occupancy, grid, _ = maps
    t = time.perf_counter()
    planner = planner_cls(cost, occupancy, grid, cfg=cfg, **CARLA_COLA, **kwargs)
    return planner, _build_cost_field(planner, (80.0, 80.0), t)


def _build_cost_field(planner, goal_xy, t: float) -> float:
    """Build the per-map part of the 2D cost field (one goal's field, then forgotten);
    returns the time since ``t`` [s]."""
    if planner.cfg.heuristic == "cost_to_go":
        planner.cost_to_go(goal_xy)
        planner.maps.cost_to_go.cache.clear()
    return time.perf_counter() - t


def make_queries(kind: str, planner: HybridAStar, world, n_queries: int, seed: int):
    """The benchmark's (start, goal) pairs for one map kind."""
    rng = np.random.default_rng(seed + 1)
    if world is not None:
        return world_hill_queries(world, rng, n_queries)
    if kind == "hill":
        def up_down(s, g):  # one end below the plateau, the other on it
            return min(s[1], g[1]) < 90.0 and max(s[1], g[1]) > 115.0
        return random_queries(planner, rng, n_queries, up_down)
    return random_queries(planner, rng, n_queries)


def time_queries(planners: dict, queries) -> tuple[dict, bool]:
    """Plan every query with every planner, back to back, alternating which goes first.

    Returns ({name: {"wall", "cpu", "expansions" (arrays), "results" (list)}}, whether
    every planner's results equal the first one's)."""
    names = list(planners)
    stats = {n: {"wall": [], "cpu": [], "expansions": [], "results": []} for n in names}
    identical = True
    for q, (start, goal) in enumerate(queries):
        for name in (names if q % 2 == 0 else names[::-1]):
            t_cpu = time.process_time()
            result = planners[name].plan(start, goal)
            stats[name]["cpu"].append(time.process_time() - t_cpu)
            stats[name]["wall"].append(result.time_s)
            stats[name]["expansions"].append(result.expansions)
            stats[name]["results"].append(result)
        first = stats[names[0]]["results"][-1]
        identical &= all(same_result(first, stats[n]["results"][-1]) for n in names[1:])
    for st in stats.values():
        for key in ("wall", "cpu", "expansions"):
            st[key] = np.asarray(st[key])
    return stats, identical


def print_stats(label: str, setup: float, st: dict) -> None:
    """One line: set-up, then per query wall and CPU time, expansions, success, cost."""
    wall, cpu, expansions = st["wall"], st["cpu"], st["expansions"]
    costs = [r.cost for r in st["results"] if r.success]
    median_cost = np.median(costs) if costs else np.nan
    print(
        f"{label:34s} map set-up {setup:5.2f} s | per query: wall median "
        f"{np.median(wall):6.3f} s, p90 {np.percentile(wall, 90):6.3f} s | CPU median "
        f"{np.median(cpu):6.3f} s, p90 {np.percentile(cpu, 90):6.3f} s, max {cpu.max():6.3f} s"
        f" | {1e6 * cpu.sum() / max(expansions.sum(), 1):5.1f} µs CPU/expansion"
        f" | expansions median {int(np.median(expansions)):6d}, max {expansions.max():6d}"
        f" | success {len(costs)}/{len(wall)} | median cost {median_cost:8.1f}", flush=True)


def print_ratio(stats: dict, identical: bool) -> None:
    """With two or more backends: the first's median time over the others', and whether
    their plans were identical."""
    names = list(stats)
    if len(names) < 2:
        return
    base = stats[names[0]]
    for name in names[1:]:
        ratio = np.median(stats[name]["wall"]) / np.median(base["wall"])
        per_query = np.median(stats[name]["wall"] / base["wall"])
        print(f"{'':34s} {name}/{names[0]}: median time ratio {ratio:.1f}× "
              f"(per-query median {per_query:.1f}×); plans identical: "
              f"{'yes' if identical else 'NO'}")


def run(kind: str, heuristic: str, n_queries: int, seed: int, cfg: PlannerConfig,
        backends=("compiled",)) -> None:
    maps = make_map(kind, seed)
    world = maps[3]
    cfg = dataclasses.replace(cfg, heuristic=heuristic)
    label = heuristic + ("" if cfg.heuristic_weight == 1 else f"×{cfg.heuristic_weight:g}")
    built = {b: make_planner(HybridAStar, maps, cfg, backend=b) for b in backends}
    queries = make_queries(kind, built[backends[0]][0], world, n_queries, seed)
    stats, identical = time_queries({b: p for b, (p, _) in built.items()}, queries)
    for b in backends:
        print_stats(f"{kind} {label} {b}", built[b][1], stats[b])
    print_ratio(stats, identical)
    if kind not in ("hill", "world_hill"):
        return
    routes = {"ascent": [], "descent": []}
    for (start, goal), result in zip(queries, stats[backends[0]]["results"], strict=True):
        if not result.success:
            continue
        direction = "ascent" if start[1] < goal[1] else "descent"
        if world is not None:  # B: through its steep section; A: round its corner
            xy = result.path[:, :2]
            lo, hi = world.landmarks["B_steep_bottom"], world.landmarks["B_steep_top"]
            on_b = np.any((np.abs(xy[:, 0] - lo[0]) < 6.0) & (xy[:, 1] > lo[1])
                          & (xy[:, 1] < hi[1]))
            on_a = np.any(np.hypot(*(xy - world.landmarks["A_corner"]).T) < 10.0)
            routes[direction].append("B" if on_b else "A" if on_a else "?")
        else:
            on_edge = result.path[np.abs(result.path[:, 1] - 102.0) < 1.0]
            routes[direction].append("B" if on_edge[:, 0].mean() > 50.0 else "A")
    for direction, taken in routes.items():
        print(f"        {direction}: routes {''.join(taken)}")


def run_experiments(profile_name: str, n_queries: int, cfg: PlannerConfig, backends,
                    experiments=("experiment1", "experiment2", "experiment3")) -> dict:
    """The experiments' own queries on the profile's costmaps from the artifact cache
    (``$DGT_DATA_DIR``; built there when missing: run ``dgt reproduce --profile P
    --stages costmaps`` first), every method and vehicle of each experiment — or, for
    ``"truth:P"``, on profile P's worlds with the slope-based cost of their true heights
    (:func:`truth_maps`, no artifacts) — planned with ``cfg`` (the profile's planner
    settings are not used: pass the exact ones). Prints a line per (experiment, vehicle,
    method, backend), then per experiment; returns the pooled wall times
    {experiment: {backend: array}}."""
    from dgt_lib.core.config import get_profile
    from dgt_lib.evaluation.experiments import EXPERIMENTS, experiment_queries
    from dgt_lib.mapping.baselines import binary_costmap
    from dgt_lib.world.terrain import get_world

    truth = profile_name.startswith("truth:")
    prof = get_profile(profile_name.removeprefix("truth:"))
    prof = prof.with_(experiments=dataclasses.replace(
        prof.experiments, n_hill=n_queries, n_ridge=n_queries, n_eval_jeep=n_queries,
        n_eval_vw_van=n_queries), planner=cfg)
    if truth:  # the worlds' true heights, no artifacts
        @functools.lru_cache(maxsize=4)
        def world_truth(world):
            cost, occupancy, grid = truth_maps(get_world(world, prof), prof.seed)
            return types.SimpleNamespace(world=world, grid=grid, occupancy=occupancy,
                                         costmaps={}, cost=cost)

        def load_maps(world, method, vehicle, profile):
            return world_truth(world)
    else:
        from dgt_lib.stages.experiments import trial_maps as load_maps
    pooled = {}
    for name in experiments:
        world, vehicles, methods = EXPERIMENTS[name]
        methods = ("truth",) if truth else methods
        queries = experiment_queries(name, prof, load_maps)
        walls = {b: [] for b in backends}
        all_identical = True
        for vehicle in vehicles:
            for method in methods:
                maps = load_maps(world, method, vehicle, prof)
                if truth:
                    cost = maps.cost
                elif method == "binary" and ("binary", vehicle) not in maps.costmaps:
                    cost = binary_costmap(maps.grid.shape)
                else:
                    cost = maps.costmap(method, vehicle)
                built = {}
                for b in backends:
                    t = time.perf_counter()
                    planner = HybridAStar.for_vehicle(cost, maps.occupancy, maps.grid,
                                                      get_vehicle(vehicle), cfg, backend=b)
                    built[b] = (planner, _build_cost_field(planner, queries[vehicle][0].goal, t))
                stats, identical = time_queries(
                    {b: p for b, (p, _) in built.items()},
                    [(q.start, q.goal) for q in queries[vehicle]])
                all_identical &= identical
                for b in backends:
                    print_stats(f"{name} {world} {vehicle} {method} {b}", built[b][1], stats[b])
                    walls[b].append(stats[b]["wall"])
                print_ratio(stats, identical)
        pooled[name] = {b: np.concatenate(w) for b, w in walls.items()}
        line = " | ".join(f"{b}: median {np.median(w):.3f} s, p90 {np.percentile(w, 90):.3f} s,"
                          f" max {w.max():.3f} s" for b, w in pooled[name].items())
        n_plans = len(pooled[name][backends[0]])
        print(f"== {name} ({world}, {n_plans} plans: {n_queries} queries × {len(methods)} "
              f"method(s) × {len(vehicles)} vehicle(s)): {line}"
              + (f" | plans identical: {'yes' if all_identical else 'NO'}"
                 if len(backends) > 1 else ""), flush=True)
    return pooled


def load_planner_module(path: str):
    """Import a planner module (e.g. a saved copy of an older ``planner.py``) from a file."""
    name = "planner_compare"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while it executes
    spec.loader.exec_module(module)
    return module


def same_result(a, b) -> bool:
    """Whether two PlanResults describe the same search: path, cost, nodes, expansions (a
    failure's wording may differ between versions: its search must not)."""
    return (a.success == b.success and (a.reason == b.reason or not a.success)
            and a.expansions == b.expansions
            and a.cost == b.cost and np.array_equal(a.path, b.path)
            and np.array_equal(a.nodes, b.nodes) and np.array_equal(a.node_costs, b.node_costs)
            and np.array_equal(a.expanded_xy, b.expanded_xy))


def compare(old_module, kind: str, heuristic: str, n_queries: int, seed: int,
            cfg: PlannerConfig, repeats: int) -> dict:
    """Time ``old_module.HybridAStar`` against this tree's on the same queries.

    Per query and repeat the two run back to back, alternating which goes first;
    the first run of each planner on a goal also pays that goal's 2D cost field.
    Returns the scenario's per-query CPU times [s] (median over repeats) and
    whether every result was identical.
    """
    maps = make_map(kind, seed)
    cfg = dataclasses.replace(cfg, heuristic=heuristic)
    planners = {"old": make_planner(old_module.HybridAStar, maps, cfg)[0],
                "new": make_planner(HybridAStar, maps, cfg)[0]}
    queries = make_queries(kind, planners["new"], maps[3], n_queries, seed)
    cpu = {"old": np.zeros((len(queries), repeats)), "new": np.zeros((len(queries), repeats))}
    expansions, identical, timed_out = [], True, 0
    for q, (start, goal) in enumerate(queries):
        for r in range(repeats):
            results = {}
            for name in (("old", "new") if (q + r) % 2 == 0 else ("new", "old")):
                t_cpu = time.process_time()
                results[name] = planners[name].plan(start, goal)
                cpu[name][q, r] = time.process_time() - t_cpu
            identical &= same_result(results["old"], results["new"])
            timed_out += "max_time_s" in results["old"].reason + results["new"].reason
        expansions.append(results["new"].expansions)
    per_query = {name: np.median(times, axis=1) for name, times in cpu.items()}
    return dict(kind=kind, heuristic=heuristic, expansions=int(np.sum(expansions)),
                identical=identical, timed_out=timed_out, **per_query)


def print_comparison(rows: list[dict], total: bool = True) -> None:
    print(f"{'scenario':24s} {'queries':>7s} {'old CPU':>9s} {'new CPU':>9s} {'new/old':>8s}"
          f" {'per-query new/old':>18s} {'old µs/exp':>10s} {'new µs/exp':>10s} identical")
    all_old, all_new = [], []
    for row in rows:
        old, new = row["old"], row["new"]
        all_old.append(old)
        all_new.append(new)
        ratios = new / old
        print(f"{row['kind'] + ' ' + row['heuristic']:24s} {len(old):7d}"
              f" {np.median(old):8.3f}s {np.median(new):8.3f}s"
              f" {np.median(new) / np.median(old):8.3f}"
              f" {np.median(ratios):8.3f} [{ratios.min():.2f}, {ratios.max():.2f}]"
              f" {1e6 * old.sum() / max(row['expansions'], 1):10.1f}"
              f" {1e6 * new.sum() / max(row['expansions'], 1):10.1f}"
              f" {'yes' if row['identical'] else 'NO'}"
              + (f" ({row['timed_out']} hit max_time_s)" if row["timed_out"] else ""))
    if not total:
        return
    old, new = np.concatenate(all_old), np.concatenate(all_new)
    print(f"{'all':24s} {len(old):7d} {np.median(old):8.3f}s {np.median(new):8.3f}s"
          f" {np.median(new) / np.median(old):8.3f} {np.median(new / old):8.3f}"
          f" | total CPU old {old.sum():.1f} s, new {new.sum():.1f} s, ratio"
          f" {new.sum() / old.sum():.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--queries", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--kinds", default="hill,random,world_hill",
                        help="hill (synthetic), random, "
                        "world_hill (dgt_lib.world.worlds.make_hill)")
    parser.add_argument("--heuristics", default="cost_to_go,euclidean")
    parser.add_argument("--max-time", type=float, default=10.0)
    parser.add_argument("--weights", default="1.0", help="heuristic_weight values, comma-separated")
    parser.add_argument("--closed-cell", type=float, default=None, help="closed_cell_m override")
    parser.add_argument("--theta-bins", type=int, default=None, help="theta_bins override")
    parser.add_argument("--compare", metavar="PATH", default=None,
                        help="a planner module file (e.g. an older planner.py) to time against "
                        "this tree's on the same queries, interleaved, checking equal results")
    parser.add_argument("--repeats", type=int, default=1,
                        help="with --compare: runs of each query per planner (median taken)")
    parser.add_argument("--backends", default="compiled",
                        help="search backends to time on the same queries, comma-separated: "
                        "compiled (the default), python (the reference)")
    parser.add_argument("--experiments", metavar="PROFILE", default=None,
                        help="instead of the synthetic maps: the hill, ridge and eval "
                        "experiments' own queries on PROFILE's costmaps from the artifact "
                        "cache in $DGT_DATA_DIR (every method and vehicle), --queries each; "
                        "truth:PROFILE: on PROFILE's worlds with the true heights' cost")
    args = parser.parse_args()
    cfg = PlannerConfig(max_time_s=args.max_time)
    if args.closed_cell is not None:
        cfg = dataclasses.replace(cfg, closed_cell_m=args.closed_cell)
    if args.theta_bins is not None:
        cfg = dataclasses.replace(cfg, theta_bins=args.theta_bins)
    print(f"PlannerConfig: {cfg}")
    print(f"load average at start: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    backends = tuple(args.backends.split(","))
    if "compiled" in backends:
        t = time.perf_counter()
        maps = make_map("random", 0)
        planner = make_planner(HybridAStar, maps, cfg)[0]
        planner.plan(*make_queries("random", planner, None, 1, 0)[0])
        print(f"warm-up of the compiled search (JIT compile or cache load, one query): "
              f"{time.perf_counter() - t:.2f} s")
    if args.experiments is not None:
        run_experiments(args.experiments, args.queries,
                        dataclasses.replace(cfg, heuristic_weight=float(args.weights)),
                        backends)
        print(f"load average at end: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
        return
    if args.compare is not None:
        old_module = load_planner_module(args.compare)
        rows = []
        for kind in args.kinds.split(","):
            for heuristic in args.heuristics.split(","):
                rows.append(compare(old_module, kind, heuristic, args.queries, args.seed,
                                    cfg, args.repeats))
                print_comparison(rows[-1:], total=False)
        print(f"\nold: {args.compare}; new: dgt_lib.navigation.planner (CPU s per query,"
              " medians; per-query new/old: median [min, max])")
        print_comparison(rows)
        return
    for kind in args.kinds.split(","):
        for heuristic in args.heuristics.split(","):
            for weight in args.weights.split(","):
                run(kind, heuristic, args.queries, args.seed,
                    dataclasses.replace(cfg, heuristic_weight=float(weight)), backends)
    print(f"load average at end: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
