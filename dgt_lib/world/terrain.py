"""The kit's four worlds, generated deterministically from their seed (:func:`get_world`).

- ``training``: hilly terrain with occasional trees and dirt paths, slopes from
  flat to beyond what the weakest vehicle climbs, bumps and sharp ridges
  (paper, Dataset: "hilly terrain with occasional trees and paths").
- ``hill`` (Experiment 1): a base and a summit plateau joined by Route A (long,
  gentle) and Route B (short, with a 26° section of 12 m rise that carla_cola
  descends but cannot ascend). Everywhere else the plateau has cliffs.
- ``ridge`` (Experiment 2): a 0.7 m sharp ridge with 14° flanks across the whole
  map width, with one smoothed section. The jeep crosses the sharp ridge, the
  mercedes_van high-centres on it but crosses the smooth section.
- ``eval`` (Experiment 3): like ``training`` from a different seed.

One more world is generated on request but built by no default stage
(:data:`EXTRA_WORLD_NAMES`):

- ``eval_hazard`` (Experiment 3 with ``ExperimentsConfig.eval_hazard_world``): the ``eval``
  world plus V-ditches the jeep's front bumper digs into (:func:`make_eval_hazard`,
  docs/worlds.md).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import ndimage

from dgt_lib.core.config import Profile, WorldsConfig, as_profile
from dgt_lib.core.geometry import GridSpec
from dgt_lib.world.worlds import (
    DIRT,
    UnknownWorldError,
    World,
    _colorize,
    _noise,
    _raster_distance,
    _smoothstep,
    polyline_distance,
)

WORLD_NAMES: tuple[str, ...] = ("training", "hill", "ridge", "eval")
"""The worlds every ``dgt reproduce`` builds (BEV, costmaps, trials)."""

EXTRA_WORLD_NAMES: tuple[str, ...] = ("eval_hazard",)
"""Worlds :func:`get_world` generates on request that no default stage builds."""


def _point_at(polyline: np.ndarray, s: float) -> tuple[float, float]:
    """The (x, y) point at arc length ``s`` [m] along a (M, 2) polyline."""
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(polyline, axis=0), axis=1))])
    return (float(np.interp(s, cum, polyline[:, 0])), float(np.interp(s, cum, polyline[:, 1])))


def _grid(size_x_m: float, size_y_m: float, resolution: float) -> GridSpec:
    return GridSpec((0.0, 0.0), resolution, (int(round(size_y_m / resolution)),
                                             int(round(size_x_m / resolution))))


def _place_trees(
    rng: np.random.Generator, grid: GridSpec, heights: np.ndarray, count: int,
    keep_out: np.ndarray, min_spacing_m: float = 4.0, margin_m: float = 3.0,
) -> np.ndarray:
    """Up to ``count`` trees at random cells not in ``keep_out`` (H, W) bool, on slopes
    below 25°, at least ``min_spacing_m`` apart. Returns (N, 4) x, y, radius, height."""
    gy, gx = np.gradient(heights.astype(np.float64), grid.resolution)
    ok = ~keep_out & (np.hypot(gx, gy) < np.tan(np.radians(25.0)))
    x0, x1, y0, y1 = grid.extent
    trees: list[tuple[float, float, float, float]] = []
    for _ in range(count * 20):
        if len(trees) >= count:
            break
        x = rng.uniform(x0 + margin_m, x1 - margin_m)
        y = rng.uniform(y0 + margin_m, y1 - margin_m)
        r, c = grid.xy_to_cell(x, y)
        if not ok[r, c]:
            continue
        if any((x - t[0]) ** 2 + (y - t[1]) ** 2 < min_spacing_m**2 for t in trees):
            continue
        trees.append((x, y, rng.uniform(0.15, 0.35), rng.uniform(4.0, 9.0)))
    return np.asarray(trees, np.float32).reshape(-1, 4)


def _random_path(rng: np.random.Generator, size_x: float, size_y: float) -> np.ndarray:
    """A smooth wandering (M, 2) polyline that enters on one map side and runs across."""
    side = rng.integers(4)
    start = {0: (0.0, rng.uniform(0.2, 0.8) * size_y), 1: (rng.uniform(0.2, 0.8) * size_x, 0.0),
             2: (size_x, rng.uniform(0.2, 0.8) * size_y),
             3: (rng.uniform(0.2, 0.8) * size_x, size_y)}[int(side)]
    heading = {0: 0.0, 1: np.pi / 2, 2: np.pi, 3: -np.pi / 2}[int(side)] + rng.uniform(-0.4, 0.4)
    pts = [np.array(start, float)]
    turn = 0.0
    for _ in range(int(2 * (size_x + size_y) / 4.0)):
        turn = 0.8 * turn + rng.normal(0.0, 0.06)
        heading += turn
        pts.append(pts[-1] + 4.0 * np.array([np.cos(heading), np.sin(heading)]))
        if not (-5 <= pts[-1][0] <= size_x + 5 and -5 <= pts[-1][1] <= size_y + 5):
            break
    return np.asarray(pts)


_EXP_UNDERFLOW = 745.2
"""exp(−x) is exactly 0.0 in float64 for x above this (the smallest subnormal is ~4.9e-324)."""


def _window(grid: GridSpec, cx: float, cy: float, radius_m: float) -> tuple[slice, slice]:
    """(rows, cols) slices of the cells whose centres lie within ``radius_m`` of (cx, cy)
    along x and y [m], with a cell to spare, clipped to the grid: a feature that is exactly
    zero farther away is computed there only — the same numbers, a fraction of the work."""
    r0, c0 = grid.xy_to_cell(cx - radius_m, cy - radius_m)
    r1, c1 = grid.xy_to_cell(cx + radius_m, cy + radius_m)
    return (slice(max(int(r0) - 1, 0), max(int(r1) + 2, 0)),
            slice(max(int(c0) - 1, 0), max(int(c1) + 2, 0)))


def make_training(
    size_m: float = 200.0, resolution: float = 0.4, seed: int = 0, name: str = "training"
) -> World:
    """Hilly terrain with occasional trees, dirt paths, bumps and sharp ridges.

    Slopes range from flat to beyond 30° (steeper than carla_cola climbs); ridges
    are 0.3–0.9 m high with 8–20° flanks, bumps 0.2–0.7 m.
    """
    rng = np.random.default_rng(seed)
    grid = _grid(size_m, size_m, resolution)
    shape = grid.shape
    res = resolution
    # Rolling hills: three octaves of smooth noise [m].
    h = (2.5 * _noise(rng, shape, 18.0 / res) + 0.6 * _noise(rng, shape, 7.0 / res)
         + 0.06 * _noise(rng, shape, 2.5 / res))
    # A few steep hills.
    X, Y = grid.cell_centers()
    for _ in range(max(1, int(size_m**2 / 6000))):
        cx, cy = rng.uniform(0.1, 0.9, 2) * size_m
        sig = rng.uniform(6.0, 12.0)
        h += rng.uniform(4.0, 9.0) * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * sig**2))
    # Sharp ridges (triangular cross-section) and bumps.
    rock = np.zeros(shape)
    for _ in range(max(2, int(size_m**2 / 1500))):
        cx, cy = rng.uniform(0.05, 0.95, 2) * size_m
        ang = rng.uniform(0, np.pi)
        length, height = rng.uniform(8.0, 30.0), rng.uniform(0.3, 0.9)
        flank = np.tan(np.radians(rng.uniform(8.0, 20.0)))
        # Zero beyond |u| > length/2 and |v| > height/flank: computed on that box only.
        w = _window(grid, cx, cy, length / 2 + height / flank)
        u = (X[w] - cx) * np.cos(ang) + (Y[w] - cy) * np.sin(ang)
        v = -(X[w] - cx) * np.sin(ang) + (Y[w] - cy) * np.cos(ang)
        along = _smoothstep(length / 2 - np.abs(u), 0.0, 2.0)
        ridge = np.clip(height - np.abs(v) * flank, 0.0, None) * along
        h[w] += ridge
        rock[w] = np.maximum(rock[w], _smoothstep(ridge, 0.15, 0.4) * (np.abs(v) < 1.5 * res))
    for _ in range(max(2, int(size_m**2 / 800))):
        cx, cy = rng.uniform(0.0, 1.0, 2) * size_m
        sig = rng.uniform(0.8, 2.0)
        # exp(−d²/2σ²) is exactly 0.0 in float64 beyond d = σ·√(2·745.2): that box only.
        w = _window(grid, cx, cy, sig * np.sqrt(2 * _EXP_UNDERFLOW))
        h[w] += rng.uniform(0.2, 0.7) * np.exp(-((X[w] - cx) ** 2 + (Y[w] - cy) ** 2)
                                               / (2 * sig**2))
    # Dirt paths: smoothed ground along wandering polylines.
    dirt = np.zeros(shape)
    routes: dict[str, np.ndarray] = {}
    for i in range(max(1, int(round(size_m / 60)))):
        path = _random_path(rng, size_m, size_m)
        routes[f"path{i}"] = path
        d = _raster_distance(grid, path)
        dirt = np.maximum(dirt, _smoothstep(-d, -2.0, -1.0))
    smooth = ndimage.gaussian_filter(h, 2.0 / res)
    h = h + 0.8 * dirt * (smooth - h)
    h = (h - h.min()).astype(np.float32)
    colors = _colorize(h, res, rng, dirt=dirt, rock=rock)
    trees = _place_trees(rng, grid, h, int(size_m**2 / 350), keep_out=dirt > 0.05)
    landmarks = {"center": (size_m / 2, size_m / 2)}
    return World(name, grid, h, colors, trees, landmarks, routes, seed)


def _profile_1d(s: np.ndarray, knots_s, knots_h, sigma_m: float, ds: float) -> np.ndarray:
    """A piecewise-linear height profile along arc length, rounded by a Gaussian of
    σ = ``sigma_m`` (crests and toes become round), sampled at ``s``."""
    fine = np.arange(-50.0, knots_s[-1] + 50.0, ds)
    prof = ndimage.gaussian_filter1d(np.interp(fine, knots_s, knots_h), sigma_m / ds,
                                     mode="nearest")
    return np.interp(s, fine, prof)


HILL_SUMMIT_M = 12.0  # summit plateau height [m]


HILL_STEEP_DEG = 26.0  # Route B's steep section [deg]


HILL_ROUTE_A_GRADE_DEG = 5.0  # Route A's ramp [deg]


CLIFF_DEG = 60.0  # plateau and embankment sides [deg]


def make_hill(resolution: float = 0.4, seed: int = 0) -> World:
    """Experiment 1's hill, 140 m × 140 m.

    Base at (30, 14), summit plateau (radius 14 m, 12 m high) centred at (30, 96).
    Route B (≈ 82 m) runs straight north from base to summit: flat, then a 26°
    section rising the full 12 m (crest and toe rounded, σ = 2.5 m), so momentum
    cannot carry a stalled truck over it. Route A (≈ 242 m) runs east to
    (110, 14), then climbs a 5° embankment north and, round the corner at
    (110, 96), west onto a level causeway to the summit. Everything else around
    the plateau and embankments is a 60° cliff. Landmarks: base, summit, the
    ends of Route B's steep section and of Route A's ramp, and Route A's corner.
    """
    rng = np.random.default_rng(seed)
    size = 140.0
    grid = _grid(size, size, resolution)
    X, Y = grid.cell_centers()
    P = np.stack([X, Y], -1)
    tan_cliff = np.tan(np.radians(CLIFF_DEG))
    ground = 0.15 * _noise(rng, grid.shape, 5.0 / resolution)
    summit = np.array([30.0, 96.0])
    r_top = 14.0
    # Plateau with cliffs.
    d_top = np.hypot(X - summit[0], Y - summit[1])
    h = np.maximum(ground, HILL_SUMMIT_M - np.clip(d_top - r_top, 0, None) * tan_cliff)
    half_w = 4.5  # route half-width [m]
    # Route B: straight north, steep section at 26°.
    route_b = np.array([[30.0, 14.0], [30.0, 40.0], [30.0, 60.0], [30.0, 82.0], [30.0, 96.0]])
    run = HILL_SUMMIT_M / np.tan(np.radians(HILL_STEEP_DEG))
    sb0 = 36.0  # arc length where the steep section starts
    d_b, s_b = polyline_distance(P, route_b)
    hb = _profile_1d(s_b, [0.0, sb0, sb0 + run, 200.0], [0.0, 0.0, HILL_SUMMIT_M, HILL_SUMMIT_M],
                     2.5, 0.1)
    emb_b = hb - np.clip(d_b - half_w, 0, None) * tan_cliff
    # Route A: east along the south, north up a long 5° ramp, level causeway west.
    route_a = np.array([[30.0, 14.0], [110.0, 14.0], [110.0, 60.0], [110.0, 96.0],
                        [70.0, 96.0], [30.0, 96.0]])
    run_a = HILL_SUMMIT_M / np.tan(np.radians(HILL_ROUTE_A_GRADE_DEG))
    sa0 = 80.0  # arc length where the ramp starts (the first corner)
    d_a, s_a = polyline_distance(P, route_a)
    ha = _profile_1d(s_a, [0.0, sa0, sa0 + run_a, 400.0],
                     [0.0, 0.0, HILL_SUMMIT_M, HILL_SUMMIT_M], 4.0, 0.1)
    emb_a = ha - np.clip(d_a - half_w, 0, None) * tan_cliff
    h = np.maximum(h, np.maximum(emb_a, emb_b))
    h = ndimage.gaussian_filter(h, 0.3 / resolution).astype(np.float32)
    h -= h.min()
    on_route = np.maximum(_smoothstep(-d_a, -half_w, -half_w + 1.5),
                          _smoothstep(-d_b, -half_w, -half_w + 1.5))
    dirt = 0.8 * on_route * (h > 0.3)
    colors = _colorize(h, resolution, rng, dirt=dirt)
    keep_out = (d_a < 10) | (d_b < 10) | (d_top < r_top + 10) | (h > 0.5)
    trees = _place_trees(rng, grid, h, 40, keep_out)
    landmarks = {
        "base": (30.0, 14.0), "summit": (30.0, 96.0),
        "B_steep_bottom": _point_at(route_b, sb0), "B_steep_top": _point_at(route_b, sb0 + run),
        "A_ramp_bottom": _point_at(route_a, sa0), "A_corner": (110.0, 96.0),
        "A_ramp_top": _point_at(route_a, sa0 + run_a),
    }
    routes = {"A": route_a, "B": route_b}
    return World("hill", grid, h, colors, trees, landmarks, routes, seed)


RIDGE_HEIGHT_M = 0.7  # sharp ridge height [m]


# Sharp ridge flanks [deg]. With 9° flanks the mercedes_van was immobilized only when
# crossing within ~20° of perpendicular; with 14° it is up to ~35° (measured), while
# the jeep still crosses at any angle.
RIDGE_FLANK_DEG = 14.0


RIDGE_SMOOTH_SIGMA_M = 6.0  # Gaussian cross-section of the smoothed crossing [m]


def make_ridge(resolution: float = 0.4, seed: int = 0) -> World:
    """Experiment 2's ridge, 100 m (x) × 80 m (y).

    A 0.7 m ridge with 14° flanks (a sharp, triangular crest) runs east–west at
    y = 40 across the whole map width, so nothing bypasses it. Around x = 75 a
    12 m wide section is smoothed into a broad Gaussian cross-section (σ = 6 m,
    0.55 m high). The sharp crest is bare rock; the smoothed section is grass.
    """
    rng = np.random.default_rng(seed)
    sx, sy = 100.0, 80.0
    grid = _grid(sx, sy, resolution)
    X, Y = grid.cell_centers()
    y_ridge, x_sharp, x_smooth = 40.0, 30.0, 75.0
    v = np.abs(Y - y_ridge)
    sharp = np.clip(RIDGE_HEIGHT_M - v * np.tan(np.radians(RIDGE_FLANK_DEG)), 0.0, None)
    smooth = 0.55 * np.exp(-(v**2) / (2 * RIDGE_SMOOTH_SIGMA_M**2))
    w = _smoothstep(-np.abs(X - x_smooth), -9.0, -6.0)  # 1 in the smoothed section
    ground = 0.2 * _noise(rng, grid.shape, 12.0 / resolution)
    ground += 0.06 * _noise(rng, grid.shape, 1.5 / resolution)
    h = (ground + (1 - w) * sharp + w * smooth).astype(np.float32)
    h -= h.min()
    rock = (1 - w) * _smoothstep(sharp, 0.05, 0.35)
    route_a = np.array([[50.0, 15.0], [x_smooth, 30.0], [x_smooth, 50.0], [50.0, 65.0]])
    route_b = np.array([[50.0, 15.0], [x_sharp, 30.0], [x_sharp, 50.0], [50.0, 65.0]])
    dirt = np.zeros(grid.shape)
    colors = _colorize(h, resolution, rng, dirt=dirt, rock=rock)
    d_routes = np.minimum(polyline_distance(np.stack([X, Y], -1), route_a)[0],
                          polyline_distance(np.stack([X, Y], -1), route_b)[0])
    keep_out = (d_routes < 8.0) | (v < 8.0)
    trees = _place_trees(rng, grid, h, 25, keep_out)
    landmarks = {"south": (50.0, 15.0), "north": (50.0, 65.0),
                 "sharp_crossing": (x_sharp, y_ridge), "smooth_crossing": (x_smooth, y_ridge)}
    return World("ridge", grid, h, colors, trees, landmarks, {"A": route_a, "B": route_b}, seed)


# Experiment 3's hazard world: written down before any method ran on it (docs/worlds.md).
DITCH_VEHICLE = "jeep"  # the vehicle whose specification sizes the ditches
DITCH_FLANK_X_APPROACH = (1.5, 1.8)  # tan φ, × the least that stops its bumper, b / 2o
DITCH_DEPTH_X_CLEARANCE = (2.0, 3.0)  # depth, × the vehicle's ground clearance
DITCH_LENGTH_M = (20.0, 40.0)  # several vehicle lengths: a detour to go round
DITCH_QUERY_M = 65.0  # mean straight-line query length (Experiment 3's 40–90 m)
DITCH_CROSSINGS_PER_QUERY = 1.0  # expected ditches on a random line of that length
BUMPER_RAISE_M = 0.1  # bumpers' underside above the belly's (world/mujoco_model.py) [m]
DITCH_LEVEL_M = 2.0  # level ground beyond each rim [m]: the flank is the ditch's own slope
DITCH_APRON_M = 15.0  # then blending back to the base terrain over this width [m]


def ditch_parameters(vehicle: str = DITCH_VEHICLE) -> dict[str, tuple[float, float]]:
    """The ditches' ranges from the vehicle's specification. A V-ditch of flank φ pitches
    the vehicle down φ with its front wheels at the bottom while the far wall rises φ: the
    ground an overhang o = (length − wheelbase)/2 ahead stands ≈ 2·o·tan φ above the
    bumper's line, which clears the ground by b = clearance + 0.1 m — the bumper digs in
    once tan φ > b / 2o. Flanks: tan φ = 1.5–1.8 × that, at most 25.5° (below Route B's
    26°, the steepest terrain the occupancy rule keeps free) [deg]; depth 2–3 × the
    clearance [m]; length [m]."""
    from dgt_lib.core.vehicles import get_vehicle

    spec = get_vehicle(vehicle)
    overhang = 0.5 * (spec.length_m - spec.wheelbase_m)
    least = (spec.ground_clearance_m + BUMPER_RAISE_M) / (2.0 * overhang)
    flank = tuple(min(float(np.degrees(np.arctan(k * least))), HILL_STEEP_DEG - 0.5)
                  for k in DITCH_FLANK_X_APPROACH)
    depth = tuple(k * spec.ground_clearance_m for k in DITCH_DEPTH_X_CLEARANCE)
    return {"flank_deg": flank, "depth_m": depth, "length_m": DITCH_LENGTH_M}


def ditch_count(size_m: float) -> int:
    """Ditches on a square map of side ``size_m`` [m]: by Buffon's needle, N segments of
    mean length ℓ̄ in area A meet a random line of length L̄ 2·L̄·ℓ̄·N / (π·A) times on
    average; N makes that :data:`DITCH_CROSSINGS_PER_QUERY` for L̄ = :data:`DITCH_QUERY_M`."""
    mean_len = 0.5 * sum(DITCH_LENGTH_M)
    n = DITCH_CROSSINGS_PER_QUERY * np.pi * size_m**2 / (2.0 * DITCH_QUERY_M * mean_len)
    return max(1, int(round(n)))


def _contour_angle(h: np.ndarray, grid: GridSpec, cx: float, cy: float,
                   radius_m: float) -> float:
    """The direction [rad, 0–π] of the contour line through (cx, cy): perpendicular to
    ``h``'s mean gradient over the cells within ``radius_m`` along x and y."""
    w = _window(grid, cx, cy, radius_m)
    gy, gx = np.gradient(h[w], grid.resolution)
    return float(np.mod(np.arctan2(gy.mean(), gx.mean()) + 0.5 * np.pi, np.pi))


def _levelled_ditch(h: np.ndarray, grid: GridSpec, centre: tuple[float, float], ang: float,
                    size: tuple[float, float, float]) -> tuple[tuple[slice, slice], np.ndarray]:
    """One V-ditch of ``size`` = (length, depth, tan φ) [m, m, m/m] along ``ang`` with
    rounded ends, on level ground: within :data:`DITCH_LEVEL_M` of the rim the ground
    takes the mean height of the ditch's bottom line, blending back to ``h`` over
    :data:`DITCH_APRON_M`. Returns the window and the cut [m]; the levelling is applied
    to ``h`` in place."""
    (cx, cy), (length, depth, flank), res = centre, size, grid.resolution
    rim = depth / flank
    w = _window(grid, cx, cy, length / 2 + rim + DITCH_LEVEL_M + DITCH_APRON_M + res)
    X, Y = grid.cell_centers()
    u = (X[w] - cx) * np.cos(ang) + (Y[w] - cy) * np.sin(ang)
    v = -(X[w] - cx) * np.sin(ang) + (Y[w] - cy) * np.cos(ang)
    # the level: the base's mean height along the bottom line (bilinear samples)
    us = np.linspace(-length / 2, length / 2, 64)
    line = ndimage.map_coordinates(h, [(cy + us * np.sin(ang) - grid.origin_xy[1]) / res - 0.5,
                                       (cx + us * np.cos(ang) - grid.origin_xy[0]) / res - 0.5],
                                   order=1, mode="nearest").mean()
    flat = rim + DITCH_LEVEL_M
    level = (_smoothstep(-np.abs(v), -(flat + DITCH_APRON_M), -flat)
             * _smoothstep(-np.abs(u), -(length / 2 + flat + DITCH_APRON_M), -length / 2 - flat))
    h[w] -= level * (h[w] - line)
    gap = np.hypot(np.clip(np.abs(u) - length / 2, 0.0, None), v)  # to the bottom line
    return w, np.clip(depth - gap * flank, 0.0, None)


def ditch_cuts(base: World, count: int, seed: int, vehicle: str = DITCH_VEHICLE
               ) -> tuple[np.ndarray, np.ndarray, list[tuple[float, float, float]]]:
    """``base``'s heights with ``count`` ditch aprons levelled, the depth [m] the ditches
    then cut into them (:func:`add_ditches`) and each ditch's centre and direction
    (x [m], y [m], angle [rad]). Every apron is levelled before any ditch is cut, so a
    later apron never fills an earlier ditch."""
    rng = np.random.default_rng((seed, 7))
    grid = base.grid
    (x0, x1, y0, y1) = grid.extent
    par = ditch_parameters(vehicle)
    h = base.heights.astype(np.float64)
    cut = np.zeros(grid.shape)
    ditches, placed = [], []
    for _ in range(count):
        cx, cy = x0 + rng.uniform(0.05, 0.95) * (x1 - x0), y0 + rng.uniform(0.05, 0.95) * (y1 - y0)
        length, depth = rng.uniform(*par["length_m"]), rng.uniform(*par["depth_m"])
        flank = np.tan(np.radians(rng.uniform(*par["flank_deg"])))
        ang = _contour_angle(h, grid, cx, cy, length / 2 + DITCH_APRON_M)
        ditches.append(_levelled_ditch(h, grid, (cx, cy), ang, (length, depth, flank)))
        placed.append((float(cx), float(cy), ang))
    for w, c in ditches:
        cut[w] += c
    return h, cut, placed


def add_ditches(base: World, count: int, seed: int, name: str,
                vehicle: str = DITCH_VEHICLE) -> World:
    """``base`` with ``count`` straight V-ditches with rounded ends, sized by
    :func:`ditch_parameters`, at uniform centres 5 % inside the map, each along the
    base's contour line there and cut into a levelled apron (:func:`_levelled_ditch`):
    the flanks keep their own slope on rolling ground, so the occupancy map leaves them
    free (docs/worlds.md). Dirt-coloured where deeper than ~0.3 m. Trees, routes and
    landmarks are kept; the base's own random stream is untouched (the ditches draw
    from theirs)."""
    h, cut, _ = ditch_cuts(base, count, seed, vehicle)
    h -= cut
    dirt = _smoothstep(cut, 0.1, 0.3)
    colors = base.colors * (1 - dirt[..., None]) + dirt[..., None] * DIRT
    h -= h.min()
    return World(name, base.grid, h.astype(np.float32), colors.astype(np.float32),
                 base.trees.copy(), dict(base.landmarks),
                 {k: r.copy() for k, r in base.routes.items()}, base.seed)


def make_eval_hazard(size_m: float = 160.0, resolution: float = 0.4, seed: int = 1000,
                     name: str = "eval_hazard") -> World:
    """The ``eval`` world (:func:`make_training` from the same seed) plus V-ditches the
    jeep's front bumper digs into (:func:`add_ditches`, :func:`ditch_count` of them):
    flanks of 21.5–25.3° on levelled aprons that the occupancy map leaves free,
    0.76–1.14 m deep, 20–40 m long. The rule and its numbers: docs/worlds.md."""
    base = make_training(size_m, resolution, seed, name=name)
    return add_ditches(base, ditch_count(size_m), seed, name)


@lru_cache(maxsize=8)
def _cached(name: str, config: WorldsConfig, seed: int) -> World:
    res = config.hfield_resolution_m
    if name == "training":
        return make_training(config.training_size_m, res, seed + config.training_seed)
    if name == "eval":
        return make_training(config.eval_size_m, res, seed + config.eval_seed, name="eval")
    if name == "eval_hazard":
        return make_eval_hazard(config.eval_size_m, res, seed + config.eval_seed)
    if name == "hill":
        return make_hill(res, seed)
    return make_ridge(res, seed)


def get_world(name: str, profile: Profile | str | None = None) -> World:
    """The generated world ``name`` (one of :data:`WORLD_NAMES` or
    :data:`EXTRA_WORLD_NAMES`) sized by ``profile`` (a :class:`Profile`, a profile name,
    or ``None`` for ``$DGT_PROFILE``).

    ``training``, ``eval`` and ``eval_hazard`` take their sizes and terrain seeds from
    ``profile.worlds``;
    ``hill`` and ``ridge`` are the same in every profile (their features are the
    experiments). The run seed (``profile.seed``) does not change any world. Worlds are
    cached in memory, per process; generating one takes at most ~0.6 s (`paper`'s 750²
    training world).
    """
    if name not in WORLD_NAMES + EXTRA_WORLD_NAMES:
        raise UnknownWorldError(f"unknown world {name!r}; valid worlds: "
                                f"{', '.join(WORLD_NAMES + EXTRA_WORLD_NAMES)}")
    prof = as_profile(profile)
    return _cached(name, prof.worlds, 0)
