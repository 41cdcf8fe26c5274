"""Deterministic planner queries whose exact (unweighted) costs are recorded in
``tests/test_planner_exact.py``: small synthetic maps, fixed seeds, no I/O.

Each case is (name, planner kwargs, start, goal). The maps:

- ``hill``: the 80 m × 60 m two-gap wall of ``tests/test_planner.py`` (0.5 m cells,
  directional cost: Route B expensive uphill), ascent and descent, both heuristics, and an
  isotropic variant;
- ``field``: 60 m × 50 m at 0.4 m, a smooth random directional cost in [0, 0.4] and round
  obstacles, random queries to goal points and goal poses;
- ``box``: PythonRobotics' own ``main()`` field (a 60 m box with two walls) on a zero
  costmap with its car (4.3 m × 2 m, centre turning radius 4.53 m), goal heading given.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.geometry import GridSpec

K = 8
HILL = dict(min_turn_radius_m=4.0, footprint=(4.0, 2.0))
FIELD = dict(min_turn_radius_m=4.5, footprint=(4.4, 2.0))
BOX = dict(min_turn_radius_m=math.hypot(3.0 / math.tan(0.6), 1.15), footprint=(4.3, 2.0))


def hill_maps():
    grid = GridSpec((0.0, 0.0), 0.5, (120, 160))
    X, Y = grid.cell_centers()
    band = (Y > 25.0) & (Y < 35.0)
    gap_b = band & (X > 34.0) & (X < 46.0)
    gap_a = band & (X > 62.0) & (X < 74.0)
    occupancy = (band & ~gap_a & ~gap_b).astype(np.uint8)
    costmap = np.full((K, *grid.shape), 0.02)
    theta = 2 * np.pi * np.arange(K) / K
    uphill_or_across = np.sin(theta) > -0.1
    costmap[:, gap_b] = np.where(uphill_or_across[:, None], 0.8, 0.05)
    costmap[:, gap_a] = 0.05
    return costmap, occupancy, grid


def field_maps(seed: int = 7):
    rng = np.random.default_rng(seed)
    grid = GridSpec((0.0, 0.0), 0.4, (125, 150))
    base = ndimage.gaussian_filter(rng.random((K, *grid.shape)), (0.0, 6.0, 6.0))
    base = (base - base.min()) / np.ptp(base)
    costmap = 0.4 * base**2
    X, Y = grid.cell_centers()
    occupancy = np.zeros(grid.shape, dtype=np.uint8)
    for _ in range(14):
        cx, cy = rng.uniform(8.0, 52.0), rng.uniform(8.0, 42.0)
        occupancy[np.hypot(X - cx, Y - cy) < rng.uniform(1.0, 3.0)] = 1
    return costmap, occupancy, grid


def box_maps():
    grid = GridSpec((-1.0, -1.0), 0.4, (155, 155))
    occupancy = np.zeros(grid.shape, dtype=np.uint8)
    walls = ((0, 0, 60, 0), (60, 0, 60, 60), (0, 60, 60, 60), (0, 0, 0, 60),
             (20, 0, 20, 40), (40, 60, 40, 20))
    for x0, y0, x1, y1 in walls:
        t = np.linspace(0.0, 1.0, 1201)
        rows, cols = grid.xy_to_cell(x0 + t * (x1 - x0), y0 + t * (y1 - y0))
        occupancy[rows, cols] = 1
    return np.zeros((K, *grid.shape)), occupancy, grid


def field_queries(seed: int = 11, n: int = 8):
    """n queries on the field map: collision-free start poses, goals 25–50 m away, every
    other one a goal pose whose footprint is free too."""
    from dgt_lib.navigation.planner import HybridAStar

    planner = HybridAStar(*field_maps(), **FIELD)
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        s = (float(rng.uniform(4, 56)), float(rng.uniform(4, 46)), float(rng.uniform(0, 2 * np.pi)))
        g = (float(rng.uniform(4, 56)), float(rng.uniform(4, 46)))
        if len(out) % 2 == 1:
            g = (*g, float(rng.uniform(0, 2 * np.pi)))
        if not 25.0 <= math.hypot(s[0] - g[0], s[1] - g[1]) <= 50.0:
            continue
        row, col = planner.grid.xy_to_cell(*g[:2])
        if planner.collides(s)[0] or planner.blocked[row, col] or (
                len(g) == 3 and planner.collides(g)[0]):
            continue
        out.append((s, g))
    return out


def cases():
    """[(name, maps builder, planner kwargs, cfg, start, goal)], the recorded queries."""
    up = ((40.0, 8.0, math.pi / 2), (40.0, 52.0))
    down = ((40.0, 52.0, -math.pi / 2), (40.0, 8.0))
    out = []
    for heuristic in ("cost_to_go", "euclidean"):
        cfg = PlannerConfig(heuristic=heuristic)
        out += [(f"hill-up-{heuristic}", "hill", HILL, cfg, *up),
                (f"hill-down-{heuristic}", "hill", HILL, cfg, *down)]
    out.append(("hill-up-isotropic", "hill_iso", HILL, PlannerConfig(), *up))
    out.append(("hill-up-noshot", "hill", HILL, PlannerConfig(analytic_shot=False), *up))
    field = field_queries()
    for i, (s, g) in enumerate(field):
        out.append((f"field-{i}", "field", FIELD, PlannerConfig(), s, g))
    out.append(("field-0-euclidean", "field", FIELD, PlannerConfig(heuristic="euclidean"),
                *field[0]))
    box_start = (10.0, 10.0 + 1.15, math.pi / 2)
    box_goal = (50.0, 50.0 - 1.15, -math.pi / 2)
    out.append(("box-main", "box", BOX, PlannerConfig(), box_start, box_goal))
    return out


def maps(name: str):
    if name == "hill":
        return hill_maps()
    if name == "hill_iso":
        costmap, occupancy, grid = hill_maps()
        return costmap.mean(axis=0, keepdims=True), occupancy, grid
    if name == "field":
        return field_maps()
    return box_maps()
