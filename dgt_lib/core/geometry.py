"""Frames, grids and heading bins: the conventions of docs/ARCHITECTURE.md in one place.

World frame: x east, y north, z up, metres. Heading θ is counter-clockwise
from +x, radians, wrapped to [0, 2π).

Grids: cell (r, c) of a :class:`GridSpec` has its centre at
``x = x0 + (c + 0.5)·res``, ``y = y0 + (r + 0.5)·res`` — rows grow with y.
Arrays are channels-first ``(C, H, W)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TWO_PI = 2.0 * np.pi


def wrap_angle(theta):
    """Wrap heading(s) θ [rad] to [0, 2π)."""
    return np.mod(theta, TWO_PI)


def angle_diff(a, b):
    """Signed smallest difference a − b [rad], in (−π, π]."""
    d = np.mod(np.asarray(a) - np.asarray(b) + np.pi, TWO_PI) - np.pi
    return np.where(d == -np.pi, np.pi, d)


def heading_bins(n_headings: int = 8) -> np.ndarray:
    """θ_k = 2πk/K for k = 0..K−1 [rad] (paper: Spatial and Angular Discretization)."""
    if n_headings < 1:
        raise ValueError(f"n_headings must be ≥ 1, got {n_headings}")
    return TWO_PI * np.arange(n_headings) / n_headings


def nearest_heading_bin(theta, n_headings: int = 8):
    """k* = argmin_k |θ_k − θ| on the circle (paper: Directional Cost Lookup)."""
    k = np.rint(wrap_angle(theta) / (TWO_PI / n_headings)).astype(np.int64)
    return np.mod(k, n_headings)


@dataclass(frozen=True)
class GridSpec:
    """A regular grid over the world: origin (x0, y0) [m] of cell (0, 0)'s corner,
    resolution [m/cell], shape (H, W) = (rows along y, columns along x)."""

    origin_xy: tuple[float, float]
    resolution: float
    shape: tuple[int, int]

    def __post_init__(self):
        if not self.resolution > 0:
            raise ValueError(f"grid resolution must be > 0 m, got {self.resolution}")
        if len(self.shape) != 2 or min(self.shape) < 1:
            raise ValueError(f"grid shape must be (H, W) with H, W ≥ 1, got {self.shape}")
        object.__setattr__(self, "origin_xy", (float(self.origin_xy[0]), float(self.origin_xy[1])))
        object.__setattr__(self, "shape", (int(self.shape[0]), int(self.shape[1])))
        object.__setattr__(self, "resolution", float(self.resolution))

    @property
    def height(self) -> int:
        return self.shape[0]

    @property
    def width(self) -> int:
        return self.shape[1]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) [m], e.g. for ``imshow(..., origin='lower')``."""
        x0, y0 = self.origin_xy
        return (x0, x0 + self.width * self.resolution, y0, y0 + self.height * self.resolution)

    def xy_to_rc(self, x, y):
        """Continuous (row, col) coordinates of world points; cell centres are integers."""
        x0, y0 = self.origin_xy
        col = (np.asarray(x, dtype=np.float64) - x0) / self.resolution - 0.5
        row = (np.asarray(y, dtype=np.float64) - y0) / self.resolution - 0.5
        return row, col

    def xy_to_cell(self, x, y):
        """Integer (row, col) of the cells containing world points (may be off-grid)."""
        x0, y0 = self.origin_xy
        col = np.floor((np.asarray(x, dtype=np.float64) - x0) / self.resolution).astype(np.int64)
        row = np.floor((np.asarray(y, dtype=np.float64) - y0) / self.resolution).astype(np.int64)
        return row, col

    def cell_to_xy(self, row, col):
        """World (x, y) [m] of cell centres."""
        x0, y0 = self.origin_xy
        x = x0 + (np.asarray(col, dtype=np.float64) + 0.5) * self.resolution
        y = y0 + (np.asarray(row, dtype=np.float64) + 0.5) * self.resolution
        return x, y

    def contains(self, x, y):
        """Whether world points lie inside the grid."""
        r, c = self.xy_to_cell(x, y)
        return (r >= 0) & (r < self.height) & (c >= 0) & (c < self.width)

    def cell_centers(self) -> tuple[np.ndarray, np.ndarray]:
        """(X, Y) arrays of shape (H, W) with every cell centre [m]."""
        rows, cols = np.mgrid[0 : self.height, 0 : self.width]
        return self.cell_to_xy(rows, cols)
