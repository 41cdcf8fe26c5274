"""The global bird's-eye-view (BEV) map (paper: Methodology → Global Map).

RGB-D frames with ground-truth camera poses are back-projected with the camera
intrinsics (:meth:`dgt_lib.core.camera.RGBDFrame.points_world`), binned into a grid
of 0.4 m cells and aggregated over *all* frames into six channels, in this order:

    R, G, B, H̄, σ_H, ‖∇H̄‖

Per cell of size Δ, with the least-squares plane z ≈ h + a·x + b·y through the cell's
points (x, y their offsets from the cell centre; :func:`fit_cell_planes`):

- R, G, B: the mean colour (0..1) of the points;
- H̄ = h [m]: the plane's height at the cell centre, which is also its mean over the cell;
- σ_H = √(s² + (a² + b²)·Δ²/12) [m]: the standard deviation of the terrain's height over
  the cell — the plane's spread over the square plus s², the points' mean squared
  residual about it (roughness, and trunks and crowns);
- ‖∇H̄‖ [m/m]: the gradient magnitude of H̄ from central differences over the four
  neighbouring cells (:func:`height_gradient`), as in the paper.

An ``observed`` mask marks the cells that received at least one point.

Where this deviates from the paper. The paper defines H̄ as "the average height per
cell" and σ_H as "the standard deviation of the height values within each cell". Taken
as the mean and std of the *points* that fell in a cell, both depend on where in the
cell the points landed: on a slope of gradient g a point at offset d from the centre
lies g·d higher, and a survey pixel covers ~0.23 m of ground, so a cell gets 1–5
points whose centroid wanders by up to ±0.2 m from cell to cell and frame to frame. On
rendered surveys of a smooth 24° ramp (g = 0.445) that put H̄ up to 10 cm off and,
doubled by the central difference, made ‖∇H̄‖ range from 0.25 to 0.61 cell to cell, with
lines of outliers where survey frames meet — above τ_s on terrain that is traversable.
Here H̄ and σ_H are the mean and std of the *terrain's* height over the cell's area,
which the points' mean and std equal when the points cover the cell evenly; for ground
that is planar at the scale of a cell they no longer depend on the sampling (on the same
surveys: H̄ within 0.14 cm, ‖∇H̄‖ within 0.014 of the truth on 10–28° ramps; 2.1 cm and
0.023 on a 1.5 m high, 30° steep Gaussian ridge, whose curvature a plane misses).
``result("points")`` gives the literal reading. ‖∇H̄‖ keeps the paper's central
differences of H̄: they are closer to the terrain's central differences than the planes'
own slopes ‖(a, b)‖ (p99 error 0.018 vs 0.072 on that ridge, 0.005 vs 0.013 on a bump,
equal on ramps; ``studies/bev_slopes.py``), and a tree's trunk and crown still stand
out with a high gradient around them.

Aggregation is streaming: a :class:`BEVAccumulator` keeps per-cell sums of the point
count, colours, offsets, heights and their products (:data:`MOMENTS`), so memory
depends on the grid, never on the number of frames, and two accumulators (e.g. from
parallel episodes) merge exactly.

Every point that lands in a cell counts, whatever it hit: tree trunks and crowns
raise H̄ and σ_H there, which is intended — a tree must come out with a high
gradient so that the occupancy map (‖∇H̄‖ > τ_s) marks it.

Example::

    acc = BEVAccumulator(grid)
    for frame in frames:
        acc.add_frame(frame)
    bev = acc.result()          # BEVMap: channels (6, H, W), observed (H, W)
"""

from __future__ import annotations

import math  # noqa: E402
from collections.abc import Iterable  # noqa: E402
from dataclasses import dataclass

import numpy as np

from dgt_lib.core.camera import RGBDFrame
from dgt_lib.core.geometry import GridSpec
from dgt_lib.perception.cell_planes import (
    _X,
    _XX,
    _XY,
    _XZ,
    _Y,
    _YY,
    _YZ,
    _Z,
    _ZZ,
    MOMENTS,
    CellPlanes,
    fit_cell_planes,
)
from dgt_lib.world.worlds import World

BEV_RESOLUTION_M = 0.4
"""BEV cell size [m] (paper: Global Map, "a single spatial grid at 0.4 m resolution")."""

CHANNEL_NAMES: tuple[str, ...] = ("R", "G", "B", "H_mean", "H_std", "H_grad")
"""The six BEV channels, in array order (docs/ARCHITECTURE.md → Conventions)."""
R, G, B, HEIGHT, HEIGHT_STD, GRADIENT = range(6)
N_CHANNELS = len(CHANNEL_NAMES)

BEV_FORMAT = 2
"""Version of the BEV statistics (:meth:`BEVAccumulator.to_sparse`) and of the channels'
definition: 1 = mean and std of the points, 2 = per-cell planes. Part of the cache keys
of the episodes and BEV maps, so that maps built by another version are rebuilt."""


def bev_grid(extent: tuple[float, float, float, float],
             resolution: float = BEV_RESOLUTION_M) -> GridSpec:
    """The BEV grid covering an area (x_min, x_max, y_min, y_max) [m], e.g. a
    world's ``grid.extent``: origin at (x_min, y_min), cells of ``resolution`` [m],
    enough rows and columns to reach x_max and y_max."""
    x_min, x_max, y_min, y_max = (float(v) for v in extent)
    if not (x_max > x_min and y_max > y_min):
        raise ValueError(f"extent must be (x_min, x_max, y_min, y_max) with max > min, "
                         f"got {extent}")
    cols = int(np.ceil((x_max - x_min) / resolution - 1e-9))
    rows = int(np.ceil((y_max - y_min) / resolution - 1e-9))
    return GridSpec((x_min, y_min), resolution, (rows, cols))


@dataclass
class BEVMap:
    """An aggregated BEV map over ``grid``.

    channels: (6, H, W) float32 — R, G, B (0..1), H̄ [m], σ_H [m], ‖∇H̄‖ [m/m].
    observed: (H, W) bool — cells that received at least one point.
    counts: (H, W) int64 — number of points per cell.
    Unobserved cells hold 0 in every channel.
    """

    grid: GridSpec
    channels: np.ndarray
    observed: np.ndarray
    counts: np.ndarray

    def __post_init__(self):
        h, w = self.grid.shape
        if self.channels.shape != (N_CHANNELS, h, w):
            raise ValueError(f"BEVMap.channels must be {(N_CHANNELS, h, w)} for grid "
                             f"{self.grid.shape}, got {self.channels.shape}")
        for name in ("observed", "counts"):
            if getattr(self, name).shape != (h, w):
                raise ValueError(f"BEVMap.{name} must be {(h, w)}, got {getattr(self, name).shape}")

    @property
    def rgb(self) -> np.ndarray:
        """(H, W, 3) float32 colour image, row 0 = southern edge (use ``origin='lower'``)."""
        return np.moveaxis(self.channels[R : B + 1], 0, -1)

    @property
    def mean_height(self) -> np.ndarray:
        """(H, W) H̄ [m]."""
        return self.channels[HEIGHT]

    @property
    def height_std(self) -> np.ndarray:
        """(H, W) σ_H [m]."""
        return self.channels[HEIGHT_STD]

    @property
    def gradient(self) -> np.ndarray:
        """(H, W) ‖∇H̄‖ [m/m]."""
        return self.channels[GRADIENT]

    def crop(self, rows: slice, cols: slice) -> BEVMap:
        """The sub-map of cells ``[rows, cols]`` (unit-step slices), with its own grid."""
        r0, r1, rs = rows.indices(self.grid.height)
        c0, c1, cs = cols.indices(self.grid.width)
        if rs != 1 or cs != 1 or r1 <= r0 or c1 <= c0:
            raise ValueError(f"crop needs non-empty unit-step slices, got {rows}, {cols}")
        x0, y0 = self.grid.origin_xy
        res = self.grid.resolution
        grid = GridSpec((x0 + c0 * res, y0 + r0 * res), res, (r1 - r0, c1 - c0))
        return BEVMap(grid, self.channels[:, r0:r1, c0:c1].copy(),
                      self.observed[r0:r1, c0:c1].copy(), self.counts[r0:r1, c0:c1].copy())

    def to_arrays(self) -> dict[str, np.ndarray]:
        """A dict of arrays for an ``.npz`` artifact (:func:`dgt_lib.core.artifacts.save`)."""
        return {
            "channels": self.channels,
            "observed": self.observed,
            "counts": self.counts,
            "grid_origin_xy": np.asarray(self.grid.origin_xy, dtype=np.float64),
            "grid_resolution": np.asarray(self.grid.resolution, dtype=np.float64),
            "grid_shape": np.asarray(self.grid.shape, dtype=np.int64),
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> BEVMap:
        """Inverse of :meth:`to_arrays` (accepts an open ``np.load`` result too)."""
        missing = {"channels", "observed", "counts", "grid_origin_xy", "grid_resolution",
                   "grid_shape"} - set(arrays)
        if missing:
            raise ValueError(f"not a BEV map: missing arrays {sorted(missing)}")
        origin = np.asarray(arrays["grid_origin_xy"], dtype=np.float64)
        grid = GridSpec((float(origin[0]), float(origin[1])),
                        float(np.asarray(arrays["grid_resolution"])),
                        tuple(int(v) for v in np.asarray(arrays["grid_shape"])))
        return cls(grid, np.asarray(arrays["channels"], dtype=np.float32),
                   np.asarray(arrays["observed"], dtype=bool),
                   np.asarray(arrays["counts"], dtype=np.int64))


def height_gradient(mean_height: np.ndarray, observed: np.ndarray,
                    resolution: float) -> np.ndarray:
    """‖∇H̄‖ [m/m] = √((∂H̄/∂x)² + (∂H̄/∂y)²) of :func:`height_gradient_components`;
    (H, W) float32, 0 on unobserved cells."""
    d_dy, d_dx = height_gradient_components(mean_height, observed, resolution)
    return np.hypot(d_dx, d_dy).astype(np.float32)


def height_gradient_components(mean_height: np.ndarray, observed: np.ndarray,
                               resolution: float) -> tuple[np.ndarray, np.ndarray]:
    """(∂H̄/∂y, ∂H̄/∂x) [m/m] by central differences over the four neighbouring cells.

        ∂H̄/∂x ≈ (H̄[r, c+1] − H̄[r, c−1]) / (2·res),
        ∂H̄/∂y ≈ (H̄[r+1, c] − H̄[r−1, c]) / (2·res),

    Where one of the two neighbours along an axis is unobserved or off the grid,
    that component is the one-sided difference with the cell itself,
    (H̄[r, c+1] − H̄[r, c]) / res or (H̄[r, c] − H̄[r, c−1]) / res; where both are,
    the component is 0. Unobserved cells get 0.

    Note: a tall object one cell wide (a thin trunk) has a central difference of
    ~0 *on its own cell* (both neighbours are low) and a high one on its four
    neighbours, so the gradient marks a ring around it; objects two or more
    cells wide (crowns) are high on every cell of their rim.

    mean_height: (H, W) [m]; observed: (H, W) bool; resolution [m/cell].
    Returns two (H, W) float64 arrays, along rows (y) and along columns (x).
    """
    h = np.where(observed, mean_height, 0.0).astype(np.float64)
    obs = np.asarray(observed, dtype=bool)
    components = []
    for axis in (0, 1):  # rows (y), columns (x)
        hp = np.zeros_like(h)
        hm = np.zeros_like(h)
        op = np.zeros_like(obs)
        om = np.zeros_like(obs)
        lead = [slice(None)] * 2
        lag = [slice(None)] * 2
        lead[axis], lag[axis] = slice(0, -1), slice(1, None)
        # hp[i] = h[i+1] (the "plus" neighbour), hm[i] = h[i-1].
        hp[tuple(lead)], op[tuple(lead)] = h[tuple(lag)], obs[tuple(lag)]
        hm[tuple(lag)], om[tuple(lag)] = h[tuple(lead)], obs[tuple(lead)]
        d = np.zeros_like(h)
        both = op & om
        d[both] = (hp[both] - hm[both]) / (2.0 * resolution)
        only_p = op & ~om
        d[only_p] = (hp[only_p] - h[only_p]) / resolution
        only_m = om & ~op
        d[only_m] = (h[only_m] - hm[only_m]) / resolution
        d[~obs] = 0.0
        components.append(d)
    return components[0], components[1]


class BEVAccumulator:
    """Streaming per-cell statistics of coloured 3D points over a grid.

    Keeps, per cell, the count n and the sums of :data:`MOMENTS` (float64): colour, the
    points' offsets (x, y) from the cell centre and height z, and their products, so
    memory is O(H·W) (104 bytes a cell) regardless of how many frames are added, and
    accumulators merge exactly. Points outside the grid are dropped. ``result()`` turns
    the sums into a :class:`BEVMap`; the accumulator can keep growing afterwards.
    """

    def __init__(self, grid: GridSpec):
        self.grid = grid
        n = grid.height * grid.width
        self._count = np.zeros(n, dtype=np.int64)
        self._sums = np.zeros((len(MOMENTS), n), dtype=np.float64)

    @property
    def n_points(self) -> int:
        """Total number of points accumulated inside the grid."""
        return int(self._count.sum())

    def add_points(self, points: np.ndarray, colors: np.ndarray) -> int:
        """Add world points (N, 3) [m] with colours (N, 3) in 0..1.

        Non-finite points and points outside the grid are dropped. Returns the
        number of points that landed in the grid.
        """
        points = np.asarray(points, dtype=np.float64)
        colors = np.asarray(colors)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {points.shape}")
        if colors.shape != points.shape:
            raise ValueError(f"colors must have shape {points.shape} like points, "
                             f"got {colors.shape}")
        if len(points) == 0:
            return 0
        # x + y + z is NaN or ±inf iff one of them is (or all are huge, hence off the grid).
        ok = np.isfinite(points[:, 0] + points[:, 1] + points[:, 2])
        if np.issubdtype(colors.dtype, np.floating):
            ok &= np.isfinite(colors[:, 0] + colors[:, 1] + colors[:, 2])
        if not ok.all():  # (indexing copies: skipped when every point is finite)
            points, colors = points[ok], colors[ok]
        g = self.grid
        row, col = g.xy_to_cell(points[:, 0], points[:, 1])
        keep = (row >= 0) & (row < g.height) & (col >= 0) & (col < g.width)
        if not keep.all():  # (indexing copies: skipped when every point is kept)
            if not keep.any():
                return 0
            points, colors, row, col = points[keep], colors[keep], row[keep], col[keep]
        flat = row * g.width + col
        vals = np.empty((len(MOMENTS), len(flat)))  # one contiguous float64 row per sum
        vals[:3] = colors.T
        vals[_X] = points[:, 0] - (g.origin_xy[0] + (col + 0.5) * g.resolution)
        vals[_Y] = points[:, 1] - (g.origin_xy[1] + (row + 0.5) * g.resolution)
        vals[_Z] = points[:, 2]
        x, y, z = vals[_X], vals[_Y], vals[_Z]
        np.multiply(x, x, out=vals[_XX])
        np.multiply(x, y, out=vals[_XY])
        np.multiply(y, y, out=vals[_YY])
        np.multiply(x, z, out=vals[_XZ])
        np.multiply(y, z, out=vals[_YZ])
        np.multiply(z, z, out=vals[_ZZ])
        # Unbuffered scatter-add: cost O(N), independent of the grid size.
        np.add.at(self._count, flat, 1)
        for k in range(len(MOMENTS)):
            np.add.at(self._sums[k], flat, vals[k])
        return len(flat)

    def add_frame(self, frame: RGBDFrame, max_depth_m: float | None = None) -> int:
        """Back-project one RGB-D frame with its pose and add its points.

        max_depth_m: optionally ignore pixels farther than this along the view
        axis [m] (far pixels cover many cells each and are the least accurate).
        Returns the number of points that landed in the grid.
        """
        if max_depth_m is not None:
            depth = np.where(frame.depth <= max_depth_m, frame.depth, np.nan)
            frame = RGBDFrame(frame.rgb, depth, frame.intrinsics, frame.position,
                              frame.rotation, frame.time_s)
        points, colors = frame.points_world()
        return self.add_points(points, colors)

    def add_frames(self, frames: Iterable[RGBDFrame], max_depth_m: float | None = None,
                   progress: bool = False) -> int:
        """Add many frames (optionally with a progress bar); returns points added."""
        if progress:
            from tqdm.auto import tqdm

            frames = tqdm(frames, desc="BEV frames", unit="frame")
        return sum(self.add_frame(f, max_depth_m=max_depth_m) for f in frames)

    def merge(self, other: BEVAccumulator) -> BEVAccumulator:
        """Add another accumulator's sums into this one (same grid); returns self."""
        if other.grid != self.grid:
            raise ValueError(f"cannot merge accumulators over different grids: "
                             f"{self.grid} vs {other.grid}")
        self._count += other._count
        self._sums += other._sums
        return self

    def to_sparse(self) -> dict[str, np.ndarray]:
        """The statistics of the cells seen so far, compactly (47 bytes a cell; an episode
        touches ~10⁴–10⁵ cells of a map of up to ~10⁶), for storing per run:

        ``cells`` (n,) int32 flat indices, ``count`` (n,) int32 points, ``rgb`` (3, n)
        uint8 mean colour, ``offset`` (2, n) float32 mean x, y offset from the cell centre
        [m], ``z`` (n,) float32 mean height [m], ``m2`` (6, n) float32 the sums of products
        of deviations from those means, Σ(x−x̄)², Σ(x−x̄)(y−ȳ), Σ(y−ȳ)², Σ(x−x̄)(z−z̄),
        Σ(y−ȳ)(z−z̄), Σ(z−z̄)² [m²], ``shape`` (2,) the grid's. :meth:`add_sparse` restores
        the sums (exactly but for the colour's 1/255 and float32 rounding).
        """
        cells = np.flatnonzero(self._count)
        n = self._count[cells].astype(np.float64)
        s = self._sums[:, cells]
        mx, my, mz = s[_X] / n, s[_Y] / n, s[_Z] / n
        m2 = np.stack([s[_XX] - n * mx * mx, s[_XY] - n * mx * my, s[_YY] - n * my * my,
                       s[_XZ] - n * mx * mz, s[_YZ] - n * my * mz, s[_ZZ] - n * mz * mz])
        m2[[0, 2, 5]] = np.maximum(m2[[0, 2, 5]], 0.0)
        rgb = np.clip(np.rint(255.0 * s[:3] / n), 0, 255)
        return {"cells": cells.astype(np.int32), "count": self._count[cells].astype(np.int32),
                "rgb": rgb.astype(np.uint8), "offset": np.stack([mx, my]).astype(np.float32),
                "z": mz.astype(np.float32), "m2": m2.astype(np.float32),
                "shape": np.asarray(self.grid.shape, np.int64)}

    def add_sparse(self, sparse: dict[str, np.ndarray]) -> BEVAccumulator:
        """Add statistics from :meth:`to_sparse` (same grid): Σ1 += n, Σc += n·c̄,
        Σx += n·x̄, …, Σxz += m2_xz + n·x̄·z̄, … Returns self."""
        if tuple(int(v) for v in sparse["shape"]) != self.grid.shape:
            raise ValueError(f"sparse BEV statistics of a {tuple(sparse['shape'])} grid "
                             f"cannot be added to a {self.grid.shape} grid")
        if "offset" not in sparse:
            raise ValueError("sparse BEV statistics of an older format (no per-cell offsets "
                             "and plane moments): rebuild them")
        cells = sparse["cells"].astype(np.int64)
        n = sparse["count"].astype(np.float64)
        mx, my = sparse["offset"].astype(np.float64)
        mz = sparse["z"].astype(np.float64)
        m2 = sparse["m2"].astype(np.float64)
        self._count[cells] += sparse["count"]
        self._sums[:3, cells] += n * sparse["rgb"] / 255.0
        self._sums[_X:, cells] += np.stack([
            n * mx, n * my, n * mz, m2[0] + n * mx * mx, m2[1] + n * mx * my,
            m2[2] + n * my * my, m2[3] + n * mx * mz, m2[4] + n * my * mz, m2[5] + n * mz * mz])
        return self

    def planes(self) -> CellPlanes:
        """The plane through each cell's points (:func:`fit_cell_planes`), (H, W) arrays."""
        h, w = self.grid.shape
        return fit_cell_planes(self._count.reshape(h, w),
                               self._sums[_X:].reshape(len(MOMENTS) - _X, h, w),
                               self.grid.resolution)

    def result(self, estimator: str = "plane") -> BEVMap:
        """The six-channel :class:`BEVMap` of everything added so far.

        Per observed cell with n points of colours c_i: colour = Σc_i/n and ‖∇H̄‖ from
        :func:`height_gradient`; H̄ and σ_H by ``estimator``:

        - ``"plane"`` (default): from the cell's plane z ≈ h + a·x + b·y of
          :meth:`planes` (residual mean square s²): H̄ = h, σ_H = √(s² + (a² + b²)·res²/12),
          the mean and std of the plane's (plus residual) heights over the cell;
        - ``"points"``: the paper read literally, the mean and (population) std of the
          points' heights, H̄ = Σz_i/n, σ_H = √max(0, Σz_i²/n − H̄²) — biased by where in
          the cell the points landed wherever the ground slopes (see the module's notes).
        """
        h, w = self.grid.shape
        res = self.grid.resolution
        count = self._count.reshape(h, w)
        sums = self._sums.reshape(len(MOMENTS), h, w)
        if estimator == "plane":
            height, a, b, resid = self.planes()
            spread = resid + (a * a + b * b) * res * res / 12.0
        elif estimator == "points":
            n = np.maximum(count, 1)
            height = sums[_Z] / n
            spread = np.maximum(sums[_ZZ] / n - height * height, 0.0)
        else:
            raise ValueError(f"estimator must be 'plane' or 'points', got {estimator!r}")
        observed = count > 0
        channels = np.zeros((N_CHANNELS, h, w), dtype=np.float32)
        channels[R : B + 1] = sums[:3] / np.maximum(count, 1)
        channels[HEIGHT] = height
        channels[HEIGHT_STD] = np.sqrt(spread)
        channels[GRADIENT] = height_gradient(channels[HEIGHT], observed, res)
        return BEVMap(self.grid, channels, observed, count.copy())


def build_bev(grid: GridSpec, frames: Iterable[RGBDFrame], max_depth_m: float | None = None,
              progress: bool = False) -> BEVMap:
    """Aggregate RGB-D frames into a :class:`BEVMap` over ``grid`` in one call."""
    acc = BEVAccumulator(grid)
    acc.add_frames(frames, max_depth_m=max_depth_m, progress=progress)
    return acc.result()


def bev_quality(bev: BEVMap, world: World) -> dict[str, float]:
    """How well a BEV map matches the true terrain.

    coverage: fraction of the cells centred in the world's interior that are
    observed. height_median_abs_err_m: median |H̄ − h| [m] over observed interior
    cells, h the true terrain height at the cell centre (tree cells included)."""
    x, y = bev.grid.cell_centers()
    x0, x1, y0, y1 = world.interior
    inside = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
    seen = inside & bev.observed
    err = np.abs(bev.mean_height[seen] - world.height_at(x[seen], y[seen]))
    return {"coverage": float(seen.sum() / max(inside.sum(), 1)),
            "height_median_abs_err_m": float(np.median(err)) if err.size else math.inf}


def changed_mask(old: BEVMap | None, new: BEVMap) -> np.ndarray | None:
    """(H, W) bool: the cells whose channels or observed flag differ between two BEV maps
    of one grid (every observed cell of ``new`` when ``old`` is None); None when nothing
    changed. What an incremental costmap update
    (:mod:`dgt_lib.beyond.incremental`) wants: with the mask instead of its
    bounding box it re-evaluates only windows that read a changed cell."""
    if old is None:
        diff = new.observed.copy()
    else:
        if old.grid != new.grid:
            raise ValueError(f"BEV maps of different grids: {old.grid} vs {new.grid}")
        diff = (old.observed != new.observed) | np.any(old.channels != new.channels, axis=0)
    return diff if diff.any() else None
