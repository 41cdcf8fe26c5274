"""Our exact Hybrid A* against PythonRobotics' teaching-grade Hybrid A*, side by side.

The anchor is ``PathPlanning/HybridAStar/hybrid_a_star.py`` of a PythonRobotics checkout
(MIT; not vendored here — pass its path). Both planners get the same obstacle fields and
the same queries, goal headings included, and run one after the other in this process, so
the ratio is taken under the same load:

- **its car**: wheelbase 3 m, max steer 0.6 rad, a 4.3 m × 2 m rectangle (3.3 m ahead of
  the rear axle, 1 m behind). The anchor's pose is the rear axle; ours is the rectangle's
  centre, 1.15 m ahead, whose minimum turning radius is √(R² + 1.15²) = 4.53 m with
  R = 3 m / tan 0.6 = 4.39 m. Queries are converted between the two.
- **obstacle fields**: walls (segments) and trees (discs). The anchor takes points — walls
  sampled every 1 m as in its own ``main()``, a tree's circle every 0.5 m; we rasterise the
  same segments, points and discs to our 0.4 m occupancy (every cell a segment or point
  touches, or whose centre is inside a disc, is occupied) with a zero costmap (K = 8), so
  only geometry prices a path.
- **scenarios**: ``main`` (its own: a 60 m box, two walls, (10, 10, 90°) → (50, 50, −90°));
  ``trees40`` and ``trees150`` (40 / 150 random trees in a 120 m box, (10, 10, 0°) →
  (110, 110, 90°); a tree is a disc of radius 0.5–1.5 m, which the anchor sees as points
  on its circle 0.5 m apart); ``wall_gap`` (an 80 m box split by a wall at y = 40 m with a
  10 m gap at its east end, (10, 10, 90°) facing the wall → (10, 70, −90°): through the gap
  and back west, arriving southward).
- **ours**: exact (``heuristic_weight`` = 1) with the ``cost_to_go`` heuristic and default
  settings otherwise. Timed as one call of the anchor is: the map set-up (footprint
  dilation, the 2D cost field and the goal's cost-to-go) plus the search — "ours" — and
  the search alone given a built planner, "plan only".
  ``--backends`` also times our pure-Python reference search (``python``) beside the
  compiled one (``compiled``, the default) on the same queries.

Run (prints the table the README quotes; the anchor's pass is the slow part)::

    .venv/bin/python benchmarks/bench_planner_anchor.py --pythonrobotics ~/src/PythonRobotics
    .venv/bin/python benchmarks/bench_planner_anchor.py --pythonrobotics PATH --repeats 3 \\
        --backends compiled,python
    .venv/bin/python benchmarks/bench_planner_anchor.py --pythonrobotics PATH --where 20

``--where N`` first runs ours N times per scenario under cProfile and prints the functions
with the most time of their own: the map set-up's steps (the distance transform, the
relaxations' terrain prices, the goal's Dijkstra) and the search (the anchor is not
profiled).
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import dataclasses
import importlib
import io
import math
import os
import pstats
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from publish import Benchmark  # benchmarks/publish.py

from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.geometry import GridSpec
from dgt_lib.navigation.planner import HybridAStar
from dgt_lib.records.study import table

SCENARIO_NAMES = {"main": "its own `main()`: 60 m box, two walls",
                  "trees40": "40 trees, 120 m box",
                  "wall_gap": "a wall with a 10 m gap at one end, 80 m box",
                  "trees150": "150 trees, 120 m box"}
"""How the table names each scenario."""

RES_M, K = 0.4, 8
WHEELBASE_M, MAX_STEER_RAD = 3.0, 0.6  # the anchor's car.py: WB, MAX_STEER
LENGTH_M, WIDTH_M, FRONT_M = 4.3, 2.0, 3.3  # LF + LB, W, LF
CENTRE_AHEAD_M = FRONT_M - LENGTH_M / 2  # rectangle centre ahead of the rear axle: 1.15 m
REAR_RADIUS_M = WHEELBASE_M / math.tan(MAX_STEER_RAD)
CENTRE_RADIUS_M = math.hypot(REAR_RADIUS_M, CENTRE_AHEAD_M)
TREE_POINT_SPACING_M = 0.5  # the anchor sees a tree as points on its circle, this far apart


@dataclasses.dataclass(frozen=True)
class Scenario:
    """An obstacle field (a square box of side ``box_m`` with walls and point trees) and
    one query, as rear-axle poses (x, y, θ) [m, m, rad]."""

    name: str
    box_m: float
    walls: tuple[tuple[float, float, float, float], ...]  # (x0, y0, x1, y1) [m]
    trees: tuple[tuple[float, float, float], ...]  # (x, y, radius) [m]
    start: tuple[float, float, float]
    goal: tuple[float, float, float]

    def segments(self):
        b = self.box_m
        return ((0.0, 0.0, b, 0.0), (b, 0.0, b, b), (0.0, b, b, b), (0.0, 0.0, 0.0, b),
                *self.walls)

    def anchor_points(self) -> tuple[list[float], list[float]]:
        """The anchor's obstacle points: segments every 1 m (its ``main()``), trees."""
        ox, oy = [], []
        for x0, y0, x1, y1 in self.segments():
            n = max(1, round(math.hypot(x1 - x0, y1 - y0)))
            for t in np.linspace(0.0, 1.0, n + 1):
                ox.append(float(x0 + t * (x1 - x0)))
                oy.append(float(y0 + t * (y1 - y0)))
        for x, y, r in self.trees:
            n = max(3, math.ceil(2 * math.pi * r / TREE_POINT_SPACING_M))
            for a in 2 * math.pi * np.arange(n) / n:
                ox.append(float(x + r * math.cos(a)))
                oy.append(float(y + r * math.sin(a)))
        return ox, oy

    def occupancy(self) -> tuple[np.ndarray, GridSpec]:
        """Our (H, W) occupancy at 0.4 m over the box plus 1 m: every cell a segment or
        tree point touches is occupied."""
        n = math.ceil((self.box_m + 2.0) / RES_M)
        grid = GridSpec((-1.0, -1.0), RES_M, (n, n))
        occ = np.zeros(grid.shape, dtype=np.uint8)
        X, Y = grid.cell_centers()
        for x, y, r in self.trees:
            occ[np.hypot(X - x, Y - y) <= r] = 1
        ox, oy = self.anchor_points()  # the trees' rings and the walls' 1 m points
        pts = [np.column_stack([ox, oy])]
        for x0, y0, x1, y1 in self.segments():
            t = np.linspace(0.0, 1.0, math.ceil(math.hypot(x1 - x0, y1 - y0) / (RES_M / 8)) + 1)
            pts.append(np.stack([x0 + t * (x1 - x0), y0 + t * (y1 - y0)], axis=1))
        pts = np.concatenate(pts)
        rows, cols = grid.xy_to_cell(pts[:, 0], pts[:, 1])
        occ[rows, cols] = 1
        return occ, grid


def _rear_to_centre(pose):
    x, y, th = pose
    return (x + CENTRE_AHEAD_M * math.cos(th), y + CENTRE_AHEAD_M * math.sin(th), th)


def _random_trees(n: int, box_m: float, keep_clear, seed: int):
    """n trees (x, y, radius) [m], radius 0.5–1.5 m, none within 6 m of ``keep_clear``."""
    rng = np.random.default_rng(seed)
    trees = []
    while len(trees) < n:
        x, y = rng.uniform(3.0, box_m - 3.0, 2)
        r = rng.uniform(0.5, 1.5)
        if all(math.hypot(x - cx, y - cy) > 6.0 + r for cx, cy in keep_clear):
            trees.append((float(x), float(y), float(r)))
    return tuple(trees)


def scenarios(seed: int = 0) -> dict[str, Scenario]:
    d = math.radians
    main = Scenario("main", 60.0, ((20.0, 0.0, 20.0, 40.0), (40.0, 60.0, 40.0, 20.0)), (),
                    (10.0, 10.0, d(90.0)), (50.0, 50.0, d(-90.0)))
    ends = ((10.0, 10.0), (110.0, 110.0))
    out = {"main": main}
    for n in (40, 150):
        out[f"trees{n}"] = Scenario(f"trees{n}", 120.0, (), _random_trees(n, 120.0, ends, seed),
                                    (10.0, 10.0, 0.0), (110.0, 110.0, d(90.0)))
    out["wall_gap"] = Scenario("wall_gap", 80.0, ((0.0, 40.0, 70.0, 40.0),), (),
                               (10.0, 10.0, d(90.0)), (10.0, 70.0, d(-90.0)))
    return out


# --- the anchor -----------------------------------------------------------------------------


def load_anchor(root: str):
    """Import PythonRobotics' hybrid_a_star.py by path, animation off."""
    os.environ.setdefault("MPLBACKEND", "Agg")
    folder = Path(root).expanduser().resolve() / "PathPlanning" / "HybridAStar"
    if not (folder / "hybrid_a_star.py").exists():
        raise SystemExit(f"no PathPlanning/HybridAStar/hybrid_a_star.py under {root}")
    sys.path.insert(0, str(folder))  # it imports car, dynamic_programming_heuristic by name
    module = importlib.import_module("hybrid_a_star")
    module.show_animation = False
    module.rs.show_animation = False
    return module


def anchor_commit(root: str) -> str:
    """The checkout's commit, short (its ``COMMIT`` file where it is no git checkout)."""
    try:
        return subprocess.run(["git", "-C", root, "rev-parse", "--short=7", "HEAD"], check=True,
                              capture_output=True, text=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = Path(root).expanduser() / "COMMIT"
        return commit.read_text().strip()[:7] if commit.exists() else "unknown"


def run_anchor(anchor, sc: Scenario) -> dict:
    ox, oy = sc.anchor_points()
    t = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):  # it prints "path found"
        path = anchor.hybrid_a_star_planning(list(sc.start), list(sc.goal), ox, oy,
                                             anchor.XY_GRID_RESOLUTION,
                                             anchor.YAW_GRID_RESOLUTION)
    wall = time.perf_counter() - t
    xy = np.column_stack([path.x_list, path.y_list]) if path.x_list else np.zeros((0, 2))
    length = float(np.hypot(*np.diff(xy, axis=0).T).sum()) if len(xy) > 1 else math.nan
    return dict(time=wall, success=len(xy) > 0, length=length)


# --- ours -----------------------------------------------------------------------------------


OURS_CFG = PlannerConfig(heuristic="cost_to_go", heuristic_weight=1.0, max_time_s=120.0,
                         max_expansions=2_000_000)


def our_query(sc: Scenario) -> dict:
    """Our planner's inputs for ``sc``: the costmap, occupancy and grid, start and goal."""
    occ, grid = sc.occupancy()
    return dict(costmap=np.zeros((K, *grid.shape)), occupancy=occ, grid=grid,
                start=_rear_to_centre(sc.start), goal=_rear_to_centre(sc.goal))


def plan_ours(q: dict, backend: str) -> tuple[HybridAStar, object]:
    """What "ours" times: the planner built on the map (set-up), then the query planned."""
    planner = HybridAStar(q["costmap"], q["occupancy"], q["grid"],
                          min_turn_radius_m=CENTRE_RADIUS_M, footprint=(LENGTH_M, WIDTH_M),
                          cfg=OURS_CFG, backend=backend)
    return planner, planner.plan(q["start"], q["goal"])


def run_ours(sc: Scenario, backend: str) -> dict:
    q = our_query(sc)
    t = time.perf_counter()
    planner, result = plan_ours(q, backend)
    total = time.perf_counter() - t
    planner.maps.cost_to_go.cache.clear()  # the search alone needs the goal's 2D field built:
    planner.cost_to_go(q["goal"][:2])
    t = time.perf_counter()
    again = planner.plan(q["start"], q["goal"])
    plan_only = time.perf_counter() - t
    assert again.cost == result.cost and again.expansions == result.expansions
    return dict(time=total, plan=plan_only, success=result.success, cost=result.cost,
                expansions=result.expansions, length=result.length_m)


def warm_up() -> None:
    """Compile (or load from numba's cache) the compiled search before any timing."""
    sc = scenarios()["main"]
    t = time.perf_counter()
    run_ours(dataclasses.replace(sc, start=(10.0, 10.0, 1.57), goal=(12.0, 30.0, 1.57)),
             "compiled")
    print(f"warm-up of the compiled search (JIT compile or cache load): "
          f"{time.perf_counter() - t:.2f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pythonrobotics", required=True, metavar="PATH",
                        help="a PythonRobotics checkout (the folder holding PathPlanning/)")
    parser.add_argument("--scenarios", default="main,trees40,wall_gap,trees150")
    parser.add_argument("--repeats", type=int, default=1,
                        help="runs of each side per scenario, interleaved; medians are shown")
    parser.add_argument("--backends", default="compiled",
                        help="our search backends to time: compiled, python (comma-separated)")
    parser.add_argument("--seed", type=int, default=0, help="tree placement")
    parser.add_argument("--where", type=int, default=0, metavar="N",
                        help="profile N runs of ours per scenario first and print where the "
                             "time goes")
    bench = Benchmark("bench_planner_anchor", parser)
    args = parser.parse_args()
    anchor = load_anchor(args.pythonrobotics)
    # the record names the anchor's commit, not where this machine keeps its checkout
    bench.argv = ["PATH" if a == args.pythonrobotics else a for a in bench.argv]
    version = anchor_commit(args.pythonrobotics)
    backends = args.backends.split(",")
    if "compiled" in backends:
        warm_up()
    all_sc = scenarios(args.seed)
    if args.where:
        for name in args.scenarios.split(","):
            where_time_goes(all_sc[name], args.where)
    rows = []
    for name in args.scenarios.split(","):
        sc = all_sc[name]
        runs = {"anchor": [], **{b: [] for b in backends}}
        for r in range(args.repeats):
            order = ["anchor", *backends]
            for side in (order if r % 2 == 0 else order[::-1]):
                runs[side].append(run_anchor(anchor, sc) if side == "anchor"
                                  else run_ours(sc, side))
        rows.append(table_row(sc, runs, backends))
        print(" | ".join(rows[-1]), flush=True)
    columns = ["scenario", "PythonRobotics"]
    for b in backends:
        columns += [f"ours ({b})", "search only", "expansions", "speed-up"]
    columns += ["path: PythonRobotics / ours"]
    bench.finish({"anchor": table(
        f"PythonRobotics' Hybrid A* (commit {version}) against ours, set-up included "
        f"(median of {args.repeats} "
        f"run{'s' * (args.repeats > 1)} each, interleaved)", columns, rows)}, args.publish)


def where_time_goes(sc: Scenario, n: int, top: int = 12) -> None:
    """Print the functions with the most time of their own over n runs of what "ours"
    times on ``sc`` (the compiled search and each compiled set-up step are one function
    each)."""
    q = our_query(sc)
    profile = cProfile.Profile()
    profile.enable()
    for _ in range(n):
        plan_ours(q, "compiled")
    profile.disable()
    out = io.StringIO()
    pstats.Stats(profile, stream=out).sort_stats("tottime").print_stats(top)
    print(f"\n{SCENARIO_NAMES[sc.name]}: where {n} runs of ours spend their time "
          f"(profiled: read the shares)\n" + out.getvalue().split("\n\n", 2)[-1], flush=True)


def _median(runs, key):
    return float(np.median([r[key] for r in runs]))


def table_row(sc: Scenario, runs: dict, backends) -> list[str]:
    """One scenario's cells: the anchor's time, then per backend ours, the search alone,
    expansions and the speed-up, then both paths' lengths."""
    a = _median(runs["anchor"], "time")
    cells = [SCENARIO_NAMES[sc.name],
             f"{a:.2f} s" if runs["anchor"][0]["success"] else f"{a:.2f} s (no path)"]
    for b in backends:
        t, p = _median(runs[b], "time"), _median(runs[b], "plan")
        cells += [f"{t:.3f} s", f"{p:.3f} s", f"{runs[b][0]['expansions']:,}",
                  f"**{a / t:.1f}×**"]
    ours = runs[backends[0]][0]["length"]
    return cells + [f"{runs['anchor'][0]['length']:.1f} / {ours:.1f} m"]


if __name__ == "__main__":
    main()
