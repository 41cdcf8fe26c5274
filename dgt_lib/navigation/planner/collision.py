"""Footprint collision checks against the occupancy map.

The vehicle rectangle (length × width, centred on the pose) is covered by an
odd number of equal circles on its long axis (``footprint_circles``). A circle
centre is snapped to its cell, and the cell is blocked when an occupied or
unobserved cell centre lies closer than r_circle + res·√2/2, so no occupied cell
centre lies inside the vehicle rectangle at any checked pose. The blocked map carries a
blocked border wide enough that every sub-step of a primitive from an on-map pose indexes
it without clipping.
"""

from __future__ import annotations

import math

import numpy as np

from dgt_lib.core.geometry import GridSpec
from dgt_lib.navigation.planner.compiled_kernels import squared_distances


class BlockedMap:
    """The cells a footprint-circle centre may not occupy, and the checks built on them.

    occupancy: (H, W) uint8, 0 free, 1 occupied, 2 unobserved (= occupied).
    circle_offsets: (n,) [m] of the footprint circles along the heading, of
        radius ``circle_radius_m``.
    reach_m: the farthest a checked circle centre lies from the pose a
        primitive starts at (arc length + largest circle offset).
    substeps: the checked poses per primitive.

    Attributes: ``blocked`` (H, W) bool; ``occupied_distance`` (H, W) distance
    [m] from each cell centre to the nearest occupied/unobserved centre (∞ on a map
    without any);
    ``clearance_m`` the distance below which a cell is blocked.
    """

    def __init__(self, occupancy: np.ndarray, grid: GridSpec, circle_offsets: np.ndarray,
                 circle_radius_m: float, reach_m: float, substeps: int):
        res = grid.resolution
        H, W = grid.shape
        self.grid = grid
        self.circle_offsets = circle_offsets
        # scipy's distance_transform_edt(occupancy == 0) to the bit, several times faster
        # (and ∞ on a map without obstacles, where scipy's measures from beyond a corner)
        self.occupied_distance = np.sqrt(squared_distances(occupancy != 0)) * res
        self.clearance_m = circle_radius_m + res * math.sqrt(2) / 2
        self.blocked = self.occupied_distance < self.clearance_m
        # border width: ≥ 1 cell past the farthest sub-step circle of a primitive from any
        # on-map pose, so that primitive_hits needs no clipping (see there)
        self.pad = pad = math.ceil(reach_m / res) + 2
        self.padded_shape = (H + 2 * pad, W + 2 * pad)
        padded = np.ones(self.padded_shape, dtype=bool)
        padded[pad:-pad, pad:-pad] = self.blocked
        self.flat = padded.ravel()
        # primitive_hits: (row, col, 1) in 1-cell-border coordinates -> flat index
        width = self.padded_shape[1]
        self._stride = np.array([width, 1, (pad - 1) * (width + 1)], dtype=np.int64)
        self._shift = np.array([[0.0], [0.0], [1.0]])
        self._ones = np.ones(substeps * len(circle_offsets), dtype=bool)  # any() by matmul
        self._inv_res = inv_res = 1.0 / res
        # (row, col) [cells] of the origin of the map with a 1-cell border
        self.cell_origin = ((grid.origin_xy[1] - res) * inv_res,
                            (grid.origin_xy[0] - res) * inv_res)

    def collides(self, poses: np.ndarray) -> np.ndarray:
        """(N,) bool: whether the footprint at each pose (N, 3) hits an occupied or
        unobserved cell or leaves the map."""
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        res = self.grid.resolution
        x0, y0 = self.grid.origin_xy
        off = self.circle_offsets
        cx = poses[:, 0, None] + off * np.cos(poses[:, 2, None])
        cy = poses[:, 1, None] + off * np.sin(poses[:, 2, None])
        col = np.floor((cx - x0) / res).astype(np.int64) + self.pad
        row = np.floor((cy - y0) / res).astype(np.int64) + self.pad
        idx = np.ravel_multi_index((row, col), self.padded_shape, mode="clip")
        return self.flat[idx].any(axis=1)

    def primitive_hits(self, x: float, y: float, cells: np.ndarray) -> list[bool]:
        """Per primitive, whether any of its footprint circles is blocked.

        cells: (3, 3·m) circle-centre offsets of the three primitives' sub-steps
        (``TurnTable.cells``: row, col in cells, then a row of zeros), from the
        pose (x, y), which must be on the map. One matrix product, no clipping: why
        truncation finds the right cells, docs/planner.md (Footprint check).
        """
        inv_res = self._inv_res
        shift = self._shift
        shift[0, 0] = y * inv_res - self.cell_origin[0]
        shift[1, 0] = x * inv_res - self.cell_origin[1]
        idx = self._stride @ (cells + shift).astype(np.int64)
        return (self.flat[idx].reshape(3, -1) @ self._ones).tolist()
