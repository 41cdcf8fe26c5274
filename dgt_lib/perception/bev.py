"""The global bird's-eye-view (BEV) map (paper: Methodology → Global Map).

RGB-D frames with ground-truth camera poses are back-projected with the camera
intrinsics (:meth:`dgt_lib.core.camera.RGBDFrame.points_world`), binned into a grid
of 0.4 m cells and aggregated over *all* frames into six channels, in this order:

    R, G, B, H̄, σ_H, ‖∇H̄‖

R, G, B are the mean colour (0..1) of the points in a cell, H̄ their mean height
[m], σ_H the standard deviation of their heights [m] and ‖∇H̄‖ the gradient
magnitude of H̄ [m/m] from central differences over the four neighbouring cells.
An ``observed`` mask marks the cells that received at least one point.

Aggregation is streaming: a :class:`BEVAccumulator` keeps per-cell sums, sums
of squares and counts, so memory depends on the grid, never on the number of
frames, and two accumulators (e.g. from parallel episodes) merge exactly.

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
from dgt_lib.world.worlds import World

BEV_RESOLUTION_M = 0.4
"""BEV cell size [m] (paper: Global Map, "a single spatial grid at 0.4 m resolution")."""

CHANNEL_NAMES: tuple[str, ...] = ("R", "G", "B", "H_mean", "H_std", "H_grad")
"""The six BEV channels, in array order (DESIGN.md → Conventions)."""
R, G, B, HEIGHT, HEIGHT_STD, GRADIENT = range(6)
N_CHANNELS = len(CHANNEL_NAMES)


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
    """‖∇H̄‖ [m/m] by central differences over the four neighbouring cells.

        ∂H̄/∂x ≈ (H̄[r, c+1] − H̄[r, c−1]) / (2·res),
        ∂H̄/∂y ≈ (H̄[r+1, c] − H̄[r−1, c]) / (2·res),
        ‖∇H̄‖ = √((∂H̄/∂x)² + (∂H̄/∂y)²).

    Where one of the two neighbours along an axis is unobserved or off the grid,
    that component is the one-sided difference with the cell itself,
    (H̄[r, c+1] − H̄[r, c]) / res or (H̄[r, c] − H̄[r, c−1]) / res; where both are,
    the component is 0. Unobserved cells get 0.

    Note: a tall object one cell wide (a thin trunk) has a central difference of
    ~0 *on its own cell* (both neighbours are low) and a high one on its four
    neighbours, so the gradient marks a ring around it; objects two or more
    cells wide (crowns) are high on every cell of their rim.

    mean_height: (H, W) [m]; observed: (H, W) bool; resolution [m/cell].
    Returns (H, W) float32.
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
        components.append(d)
    grad = np.hypot(components[0], components[1])
    grad[~obs] = 0.0
    return grad.astype(np.float32)


class BEVAccumulator:
    """Streaming per-cell statistics of coloured 3D points over a grid.

    Keeps, per cell, the count n, Σ colour, Σ z and Σ z² (float64), so memory is
    O(H·W) regardless of how many frames are added. Points outside the grid are
    dropped. ``result()`` turns the sums into a :class:`BEVMap`; the accumulator
    can keep growing afterwards.
    """

    def __init__(self, grid: GridSpec):
        self.grid = grid
        n = grid.height * grid.width
        self._count = np.zeros(n, dtype=np.int64)
        self._sum_rgb = np.zeros((3, n), dtype=np.float64)
        self._sum_z = np.zeros(n, dtype=np.float64)
        self._sum_z2 = np.zeros(n, dtype=np.float64)

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
        colors = np.asarray(colors, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {points.shape}")
        if colors.shape != points.shape:
            raise ValueError(f"colors must have shape {points.shape} like points, "
                             f"got {colors.shape}")
        if len(points) == 0:
            return 0
        finite = np.isfinite(points).all(axis=1) & np.isfinite(colors).all(axis=1)
        points, colors = points[finite], colors[finite]
        row, col = self.grid.xy_to_cell(points[:, 0], points[:, 1])
        keep = (row >= 0) & (row < self.grid.height) & (col >= 0) & (col < self.grid.width)
        if not keep.any():
            return 0
        flat = row[keep] * self.grid.width + col[keep]
        z = points[keep, 2]
        rgb = colors[keep]
        # Unbuffered scatter-add: cost O(N), independent of the grid size.
        np.add.at(self._count, flat, 1)
        np.add.at(self._sum_z, flat, z)
        np.add.at(self._sum_z2, flat, z * z)
        for ch in range(3):
            np.add.at(self._sum_rgb[ch], flat, rgb[:, ch])
        return int(keep.sum())

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
        self._sum_rgb += other._sum_rgb
        self._sum_z += other._sum_z
        self._sum_z2 += other._sum_z2
        return self

    def to_sparse(self) -> dict[str, np.ndarray]:
        """The statistics of the cells seen so far, compactly (~19 bytes a cell; an
        episode touches ~10⁴–10⁵ cells of a map of up to ~10⁶), for storing per run:

        ``cells`` (n,) int32 flat indices, ``count`` (n,) int32 points, ``rgb`` (3, n)
        uint8 mean colour, ``z`` (n,) float32 mean height [m], ``m2`` (n,) float32
        Σ(z − z̄)² [m²], ``shape`` (2,) the grid's. :meth:`add_sparse` restores the
        sums (exactly but for the colour's 1/255 rounding).
        """
        cells = np.flatnonzero(self._count)
        n = self._count[cells].astype(np.float64)
        mean_z = self._sum_z[cells] / n
        m2 = np.maximum(self._sum_z2[cells] - n * mean_z**2, 0.0)
        rgb = np.clip(np.rint(255.0 * self._sum_rgb[:, cells] / n), 0, 255)
        return {"cells": cells.astype(np.int32), "count": self._count[cells].astype(np.int32),
                "rgb": rgb.astype(np.uint8), "z": mean_z.astype(np.float32),
                "m2": m2.astype(np.float32), "shape": np.asarray(self.grid.shape, np.int64)}

    def add_sparse(self, sparse: dict[str, np.ndarray]) -> BEVAccumulator:
        """Add statistics from :meth:`to_sparse` (same grid): Σ1 += n, Σc += n·c̄,
        Σz += n·z̄, Σz² += m2 + n·z̄². Returns self."""
        if tuple(int(v) for v in sparse["shape"]) != self.grid.shape:
            raise ValueError(f"sparse BEV statistics of a {tuple(sparse['shape'])} grid "
                             f"cannot be added to a {self.grid.shape} grid")
        cells = sparse["cells"].astype(np.int64)
        n = sparse["count"].astype(np.float64)
        z = sparse["z"].astype(np.float64)
        self._count[cells] += sparse["count"]
        self._sum_rgb[:, cells] += n * sparse["rgb"] / 255.0
        self._sum_z[cells] += n * z
        self._sum_z2[cells] += sparse["m2"] + n * z**2
        return self

    def result(self) -> BEVMap:
        """The six-channel :class:`BEVMap` of everything added so far.

        Per observed cell with n points of heights z_i and colours c_i:
        colour = Σc_i/n, H̄ = Σz_i/n, σ_H = √max(0, Σz_i²/n − H̄²) (population
        std, 0 for a single point), ‖∇H̄‖ from :func:`height_gradient`.
        """
        h, w = self.grid.shape
        n = self._count
        seen = n > 0
        safe_n = np.maximum(n, 1)
        mean_z = np.where(seen, self._sum_z / safe_n, 0.0)
        var_z = np.where(seen, self._sum_z2 / safe_n - mean_z**2, 0.0)
        std_z = np.sqrt(np.maximum(var_z, 0.0))
        rgb = np.where(seen, self._sum_rgb / safe_n, 0.0)
        observed = seen.reshape(h, w)
        channels = np.zeros((N_CHANNELS, h, w), dtype=np.float32)
        channels[R : B + 1] = rgb.reshape(3, h, w)
        channels[HEIGHT] = mean_z.reshape(h, w)
        channels[HEIGHT_STD] = std_z.reshape(h, w)
        channels[GRADIENT] = height_gradient(channels[HEIGHT], observed, self.grid.resolution)
        return BEVMap(self.grid, channels, observed, n.reshape(h, w).copy())


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
