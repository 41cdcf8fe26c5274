"""Worlds: terrain heights, colour texture, trees and named landmarks.

A :class:`World` is the ground truth the simulator is built from and the figures
are drawn from. Heights live on a :class:`~dgt_lib.core.geometry.GridSpec` (docs/ARCHITECTURE.md:
x along columns, y along rows, cell centres at ``x0 + (c + ½)·res``); the MuJoCo
heightfield puts one vertex at every cell centre. Colours (float32 RGB in 0..1) carry
information: grass on gentle ground, brown dirt on paths and routes, grey rock on steep
slopes and sharp crests.

The kit's four worlds are generated in :mod:`dgt_lib.world.terrain`
(:func:`~dgt_lib.world.terrain.get_world`); bring your own terrain with
:func:`from_heightmap` / :func:`load_heightmap`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import ndimage

from dgt_lib.core.geometry import GridSpec

TREE_COLUMNS: tuple[str, ...] = ("x", "y", "radius", "height")
PATCH_SIZE_M: tuple[float, float] = (8.8, 2.8)  # paper: Patches


class UnknownWorldError(ValueError):
    """A world name that is not one of :data:`WORLD_NAMES`."""


class HeightmapError(ValueError):
    """A height map that cannot become a :class:`World` (shape, dtype, values, file)."""


@dataclass(frozen=True, eq=False)
class World:
    """Terrain, colours, trees and landmarks of one map.

    grid: the height grid (H, W) at ``grid.resolution`` metres per cell.
    heights: (H, W) float32, metres (z up). colors: (H, W, 3) float32 RGB in 0..1.
    trees: (N, 4) float32, columns :data:`TREE_COLUMNS` = x [m], y [m], trunk
    radius [m], height [m]. landmarks: name → (x, y) [m]. routes: name → (M, 2)
    waypoint polyline [m] (e.g. the hill's "A" and "B"). The arrays are read-only
    (copy before editing, then build a new world with :func:`from_heightmap`).
    """

    name: str
    grid: GridSpec
    heights: np.ndarray
    colors: np.ndarray
    trees: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), np.float32))
    landmarks: dict[str, tuple[float, float]] = field(default_factory=dict)
    routes: dict[str, np.ndarray] = field(default_factory=dict)
    seed: int | None = None

    def __post_init__(self):
        # Worlds are shared (get_world caches them): their arrays are read-only.
        for arr in (self.heights, self.colors, self.trees, *self.routes.values()):
            arr.setflags(write=False)

    @property
    def resolution(self) -> float:
        """Grid resolution [m/cell]."""
        return self.grid.resolution

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """Area covered by the cells, (x_min, x_max, y_min, y_max) [m]."""
        return self.grid.extent

    @property
    def interior(self) -> tuple[float, float, float, float]:
        """Area spanned by the cell centres (the heightfield's extent) [m]."""
        x0, x1, y0, y1 = self.grid.extent
        h = 0.5 * self.grid.resolution
        return (x0 + h, x1 - h, y0 + h, y1 - h)

    def height_at(self, x, y) -> np.ndarray:
        """Terrain height [m] at world points, bilinear between cell centres
        (clamped to the border cells outside the grid). Shaped like x and y."""
        x, y = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(y, np.float64))
        row, col = self.grid.xy_to_rc(x, y)
        h, w = self.heights.shape
        row = np.clip(row, 0.0, h - 1.0)
        col = np.clip(col, 0.0, w - 1.0)
        r0 = np.minimum(row.astype(np.int64), max(h - 2, 0))
        c0 = np.minimum(col.astype(np.int64), max(w - 2, 0))
        fr, fc = row - r0, col - c0
        r1, c1 = np.minimum(r0 + 1, h - 1), np.minimum(c0 + 1, w - 1)
        z = self.heights
        top = z[r0, c0] * (1 - fc) + z[r0, c1] * fc
        bottom = z[r1, c0] * (1 - fc) + z[r1, c1] * fc
        return (top * (1 - fr) + bottom * fr).astype(np.float64)

    def gradient(self) -> tuple[np.ndarray, np.ndarray]:
        """(∂h/∂x, ∂h/∂y), each (H, W), central differences [m/m]."""
        gy, gx = np.gradient(self.heights.astype(np.float64), self.grid.resolution)
        return gx, gy

    def slope_deg(self) -> np.ndarray:
        """Steepest slope of every cell, (H, W) degrees."""
        gx, gy = self.gradient()
        return np.degrees(np.arctan(np.hypot(gx, gy)))

    def tree_distance(self, x, y) -> np.ndarray:
        """Horizontal distance [m] from world points to the nearest tree trunk surface
        (inf without trees), e.g. to keep spawn poses clear of trees."""
        x, y = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(y, np.float64))
        if len(self.trees) == 0:
            return np.full(x.shape, np.inf)
        t = self.trees.astype(np.float64)
        d = np.hypot(x[..., None] - t[:, 0], y[..., None] - t[:, 1]) - t[:, 2]
        return d.min(axis=-1)

    def on_route(self, path_xy: np.ndarray, route: str, tolerance_m: float = 6.0) -> bool:
        """Whether every point of a (N, 2) path lies within ``tolerance_m`` of a route."""
        d = polyline_distance(np.asarray(path_xy, float), self.routes[route])[0]
        return bool(np.all(d <= tolerance_m))


# ----------------------------------------------------------------------------- helpers


def polyline_distance(points: np.ndarray, polyline: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance [m] of (..., 2) points to a (M, 2) polyline and the arc length [m] of
    the nearest polyline point. Returns two arrays shaped like ``points[..., 0]``."""
    p = np.asarray(points, np.float64)
    a, b = polyline[:-1].astype(np.float64), polyline[1:].astype(np.float64)
    seg = b - a
    seg_len = np.linalg.norm(seg, axis=1)
    s0 = np.concatenate([[0.0], np.cumsum(seg_len)])[:-1]
    best_d = np.full(p.shape[:-1], np.inf)
    best_s = np.zeros(p.shape[:-1])
    for i in range(len(seg)):
        t = np.clip(((p - a[i]) @ seg[i]) / max(seg_len[i] ** 2, 1e-12), 0.0, 1.0)
        d = np.linalg.norm(p - (a[i] + t[..., None] * seg[i]), axis=-1)
        better = d < best_d
        best_d = np.where(better, d, best_d)
        best_s = np.where(better, s0[i] + t * seg_len[i], best_s)
    return best_d, best_s


def _raster_distance(grid: GridSpec, polyline: np.ndarray) -> np.ndarray:
    """(H, W) distance [m] from every cell centre to a (M, 2) polyline, by a Euclidean
    distance transform of the rasterised polyline (exact to about half a cell)."""
    seg_len = np.linalg.norm(np.diff(polyline, axis=0), axis=1)
    n = max(2, int(seg_len.sum() / (0.5 * grid.resolution)))
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    s = np.linspace(0.0, cum[-1], n)
    r, c = grid.xy_to_cell(np.interp(s, cum, polyline[:, 0]), np.interp(s, cum, polyline[:, 1]))
    ok = (r >= 0) & (r < grid.height) & (c >= 0) & (c < grid.width)
    free = np.ones(grid.shape, bool)
    free[r[ok], c[ok]] = False
    if free.all():
        return np.full(grid.shape, np.inf)
    return ndimage.distance_transform_edt(free) * grid.resolution


# ----------------------------------------------------------------------------- your own terrain


def from_heightmap(
    heights: np.ndarray,
    resolution: float,
    *,
    origin: tuple[float, float] = (0.0, 0.0),
    colors: np.ndarray | None = None,
    trees=(),
    landmarks: dict[str, tuple[float, float]] | None = None,
    name: str = "heightmap",
) -> World:
    """A :class:`World` from a (H, W) array of heights [m]: x along columns, y along
    rows (row 0 at ``origin``'s y), cell (r, c) centred at
    ``origin + ((c + ½)·res, (r + ½)·res)``.

    colors: optional (H, W, 3) RGB, float in 0..1 or uint8 (default: slope-based
    grass/rock). trees: optional (N, 4) x, y, radius, height [m].
    Raises :class:`HeightmapError` for a wrong rank or dtype, heights that are NaN/inf
    as float32 (the world's dtype: 1e40 passes as float64 and is inf as float32), a
    map smaller than one 8.8 m × 2.8 m patch, resolution ≤ 0, or bad colours/trees.
    """
    arr = np.asarray(heights)
    if arr.ndim != 2:
        raise HeightmapError(f"heights must be a 2-D (H, W) array, got shape {arr.shape}")
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise HeightmapError(f"heights must be a real-valued array, got dtype {arr.dtype}")
    try:
        res = float(resolution)
    except (TypeError, ValueError):
        raise HeightmapError(f"resolution must be a number of metres, got {resolution!r}") from None
    if not (np.isfinite(res) and res > 0):
        raise HeightmapError(f"resolution must be > 0 m, got {resolution}")
    with np.errstate(over="ignore"):
        hm = arr.astype(np.float32)  # what MuJoCo and the maps use
    if not np.all(np.isfinite(hm)):
        bad = int(np.count_nonzero(~np.isfinite(hm)))
        raise HeightmapError(f"heights contain {bad} values that are NaN/inf or beyond float32's "
                             f"range (|h| > {np.finfo(np.float32).max:.1e} m)")
    min_cells = int(np.ceil(PATCH_SIZE_M[1] / res - 1e-9))
    long_cells = int(np.ceil(PATCH_SIZE_M[0] / res - 1e-9))
    h, w = arr.shape
    if min(h, w) < min_cells or max(h, w) < long_cells:
        raise HeightmapError(
            f"height map of {h}×{w} cells at {res} m is smaller than one "
            f"{PATCH_SIZE_M[0]} m × {PATCH_SIZE_M[1]} m patch "
            f"(needs at least {long_cells}×{min_cells} cells)")
    grid = GridSpec(tuple(origin), res, (h, w))
    if colors is None:
        rgb = _colorize(hm, res, np.random.default_rng(0))
    else:
        c = np.asarray(colors)
        if c.shape != (h, w, 3):
            raise HeightmapError(f"colors must have shape {(h, w, 3)}, got {c.shape}")
        if c.dtype == np.uint8:
            rgb = c.astype(np.float32) / 255.0
        elif np.issubdtype(c.dtype, np.floating) and np.all(np.isfinite(c)):
            if c.min() < 0.0 or c.max() > 1.0:
                raise HeightmapError("float colors must lie in 0..1")
            rgb = c.astype(np.float32)
        else:
            raise HeightmapError(f"colors must be uint8 or finite floats, got {c.dtype}")
    tr = np.asarray(trees, np.float64).reshape(-1, 4) if len(trees) else np.zeros((0, 4))
    with np.errstate(over="ignore"):
        tr = tr.astype(np.float32)
    if not np.all(np.isfinite(tr)) or np.any(tr[:, 2:] <= 0):
        raise HeightmapError("trees must be finite float32 (N, 4) rows x, y, radius > 0, "
                             "height > 0")
    return World(name, grid, hm, rgb, tr, dict(landmarks or {}), {}, None)


def load_heightmap(
    path: str | Path,
    resolution: float,
    *,
    vertical_scale_m: float | None = None,
    origin: tuple[float, float] = (0.0, 0.0),
    name: str | None = None,
) -> World:
    """A :class:`World` from a file: ``.npy`` (heights in metres) or a greyscale PNG
    (8- or 16-bit; height = pixel / max_pixel_value · ``vertical_scale_m``). A height map
    has no colour, and none is invented: its world is one grey (:func:`no_imagery`).

    Image row 0 is the top of the picture, i.e. the north (largest y) edge, so a
    map looks in a figure (``origin='lower'``) as it looks in an image viewer.
    """
    p = Path(path)
    if not p.is_file():
        raise HeightmapError(f"height map file not found: {p}")
    suffix = p.suffix.lower()
    if suffix == ".npy":
        try:
            arr = np.load(p, allow_pickle=False)
        except Exception as exc:
            raise HeightmapError(f"cannot read {p} as a .npy array: {exc}") from None
    elif suffix == ".png":
        import cv2

        img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise HeightmapError(f"cannot read {p} as an image")
        if img.ndim != 2:
            raise HeightmapError(f"{p} must be a greyscale PNG, got shape {img.shape}")
        if vertical_scale_m is None or not vertical_scale_m > 0:
            raise HeightmapError("a PNG height map needs vertical_scale_m > 0 (metres at full "
                                 "scale)")
        full = 65535.0 if img.dtype == np.uint16 else 255.0
        arr = img[::-1].astype(np.float64) / full * float(vertical_scale_m)
    else:
        raise HeightmapError(f"unsupported height map format {suffix!r}: use .npy or .png")
    return from_heightmap(arr, resolution, origin=origin, name=name or p.stem,
                          colors=no_imagery(arr.shape))


NO_IMAGERY_GREY = 0.5
"""The albedo of a height map's or DEM's world without imagery, the same everywhere: its
map's RGB then holds nothing the file does not (no rock painted where it is steep)."""


def no_imagery(shape: tuple[int, ...]) -> np.ndarray:
    """The colours (H, W, 3) of a world whose file has no imagery: one grey."""
    return np.full((*shape[:2], 3), NO_IMAGERY_GREY, np.float32)


GRASS = np.array([0.32, 0.50, 0.20], np.float32)


GRASS_DRY = np.array([0.55, 0.58, 0.30], np.float32)


DIRT = np.array([0.55, 0.40, 0.25], np.float32)


ROCK = np.array([0.50, 0.49, 0.47], np.float32)


def _colorize(
    heights: np.ndarray, resolution: float, rng: np.random.Generator,
    dirt: np.ndarray | None = None, rock: np.ndarray | None = None,
) -> np.ndarray:
    """Grass (with dry patches) on gentle ground, dirt where ``dirt`` (H, W) in 0..1,
    rock on slopes above ~22° or where ``rock`` (H, W) in 0..1. Returns (H, W, 3)."""
    gy, gx = np.gradient(heights.astype(np.float64), resolution)
    slope = np.degrees(np.arctan(np.hypot(gx, gy)))
    dry = _smoothstep(_noise(rng, heights.shape, 6.0 / resolution), -0.3, 1.2)[..., None]
    speckle = 0.04 * rng.standard_normal(heights.shape + (1,))
    col = (1 - dry) * GRASS + dry * GRASS_DRY
    w_rock = _smoothstep(slope, 20.0, 28.0)
    if rock is not None:
        w_rock = np.maximum(w_rock, rock)
    if dirt is not None:
        col = (1 - dirt[..., None]) * col + dirt[..., None] * DIRT
    col = (1 - w_rock[..., None]) * col + w_rock[..., None] * ROCK
    return np.clip(col + speckle, 0.0, 1.0).astype(np.float32)


def _smoothstep(x, lo: float, hi: float):
    t = np.clip((np.asarray(x, np.float64) - lo) / (hi - lo), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _noise(rng: np.random.Generator, shape, sigma_cells: float) -> np.ndarray:
    """Smooth noise with unit standard deviation (in expectation, whatever the map
    size), correlation length ~σ cells: white noise through a Gaussian filter,
    divided by the filter's gain 1 / (2·√π·σ)."""
    n = ndimage.gaussian_filter(rng.standard_normal(shape), sigma_cells, mode="wrap")
    return n * (2.0 * np.sqrt(np.pi) * sigma_cells)
