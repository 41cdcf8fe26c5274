"""Heading-aligned BEV patches (paper: Methodology → Patches, Costmap Construction).

A patch is 8.8 m × 2.8 m = 22 × 7 cells of 0.4 m, centred on the vehicle, cut in
the vehicle's frame: **row 0 is the row the vehicle drives toward** (forward =
"up") and **column 0 is the vehicle's left**, so a patch shown as an image (row 0
at the top) looks like the terrain seen from above with the vehicle facing up.

Patch cell (i, j) has its centre at the body-frame offset

    forward = (10.5 − i)·0.4 m,   left = (3 − j)·0.4 m,

(:func:`patch_offsets`), i.e. at the world point
``(x, y) + forward·(cos θ, sin θ) + left·(−sin θ, cos θ)`` for a pose (x, y, θ).
Every value is sampled from the BEV by bilinear interpolation (``cv2.remap``).

Training cuts one patch per pose (:func:`extract_patches`). Inference follows the
paper's procedure, "rotate the BEV by −θ_k, slide a window, rotate back":
:func:`rotate_map` resamples the whole map with the same sampler so that heading
θ points up, and a plain 22 × 7 window over the rotated image
(:func:`sliding_windows`) *is* the patch :func:`extract_patches` returns at the
window's centre with heading θ — training and inference cannot disagree.
:func:`unrotate_map` brings per-pixel results of the rotated frame back onto the
BEV grid.

Masks: a sampled value is ``observed`` when every BEV cell with a non-zero
bilinear weight (weight > 1e-4) was observed, so values never mix in the zeros
of unobserved cells; points off the map are unobserved. Unobserved samples hold
whatever the interpolation gives (0 far from observed cells) — use the mask.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np

from dgt_lib.core.geometry import GridSpec
from dgt_lib.perception.bev import N_CHANNELS, BEVMap

PATCH_ROWS = 22
"""Cells along the vehicle's forward axis (8.8 m / 0.4 m)."""
PATCH_COLS = 7
"""Cells across the vehicle (2.8 m / 0.4 m)."""
PATCH_RES = 0.4
"""Patch cell size [m], equal to the BEV resolution."""
PATCH_LENGTH_M = PATCH_ROWS * PATCH_RES  # 8.8 m, paper: Patches
PATCH_WIDTH_M = PATCH_COLS * PATCH_RES  # 2.8 m, paper: Patches

_ROW_CENTER = (PATCH_ROWS - 1) / 2.0  # 10.5: the vehicle sits between rows 10 and 11
_COL_CENTER = (PATCH_COLS - 1) / 2.0  # 3.0: the vehicle sits on column 3
_OBSERVED_MIN = 1.0 - 1e-4  # interpolated mask ≥ this ⇔ all weighted neighbours observed
_CHUNK = 4096  # poses per cv2.remap call (cv2 needs image sides < 32767)


def patch_offsets(resolution: float = PATCH_RES, margin: int = 0) -> np.ndarray:
    """(22, 7, 2) body-frame offsets (forward, left) [m] of the patch cell centres.

    offsets[i, j] = ((10.5 − i)·res, (3 − j)·res): row 0 is 4.2 m ahead, row 21
    4.2 m behind; column 0 is 1.2 m to the left, column 6 1.2 m to the right.
    ``margin`` > 0: the patch with that many cells of context on every side,
    (22 + 2m, 7 + 2m, 2), the patch itself at [m : m + 22, m : m + 7].
    """
    m = int(margin)
    if m < 0:
        raise ValueError(f"margin must be ≥ 0 cells, got {margin}")
    i, j = np.mgrid[-m : PATCH_ROWS + m, -m : PATCH_COLS + m].astype(np.float64)
    return np.stack([(_ROW_CENTER - i) * resolution, (_COL_CENTER - j) * resolution], axis=-1)


def forward_grade(patches: np.ndarray) -> np.ndarray:
    """(n,) dH̄/d(forward) of each (n, 6, 22, 7) patch [m/m]: the least-squares slope of
    the centre columns' mean height against the forward offset. Negative = downhill in
    the patch's heading; arctan gives the grade angle."""
    h = np.asarray(patches[:, 3], np.float64)[:, :, 2:5].mean(axis=2)  # (n, 22)
    forward = (_ROW_CENTER - np.arange(PATCH_ROWS)) * PATCH_RES
    f = forward - forward.mean()
    hc = h - np.nanmean(h, axis=1, keepdims=True)
    return np.nansum(hc * f, axis=1) / np.sum(f * f)


def body_to_world(poses: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World (x, y) [m] of body-frame offsets for each pose.

    poses: (N, 3) [x m, y m, θ rad]; offsets: (..., 2) (forward, left) [m].
    Returns x, y of shape (N, ...).
    """
    poses = np.asarray(poses, dtype=np.float64)
    x, y, th = poses[:, 0], poses[:, 1], poses[:, 2]
    extra = (None,) * (offsets.ndim - 1)
    c, s = np.cos(th)[(...,) + extra], np.sin(th)[(...,) + extra]
    f, l = offsets[..., 0], offsets[..., 1]
    return x[(...,) + extra] + f * c - l * s, y[(...,) + extra] + f * s + l * c


def _bev_image(bev: BEVMap) -> tuple[np.ndarray, np.ndarray]:
    h, w = bev.grid.shape
    if max(h, w) >= np.iinfo(np.int16).max:
        raise ValueError(f"BEV grid {bev.grid.shape} too large for cv2.remap (sides < 32767)")
    image = np.ascontiguousarray(np.moveaxis(bev.channels, 0, -1), dtype=np.float32)
    return image, bev.observed.astype(np.float32)


def _remap(image: np.ndarray, map_col: np.ndarray, map_row: np.ndarray) -> np.ndarray:
    return cv2.remap(image, map_col, map_row, interpolation=cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def sample_bev(bev: BEVMap, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bilinearly sample all BEV channels at world points.

    x, y: (A, B) [m] (2-D, sides < 32767). Returns channels (6, A, B) float32 and
    observed (A, B) bool (see the module docstring for the mask rule).
    This is the one sampler behind both :func:`extract_patches` and :func:`rotate_map`.
    """
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    if x.ndim != 2 or x.shape != y.shape or max(x.shape) >= np.iinfo(np.int16).max:
        raise ValueError(f"x and y must be equal 2-D arrays with sides < 32767, "
                         f"got {x.shape} and {y.shape}")
    image, obs = _bev_image(bev)
    return _sample_image(image, obs, bev.grid, x, y)


def _sample_image(image: np.ndarray, obs: np.ndarray, grid: GridSpec, x: np.ndarray,
                  y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    row, col = grid.xy_to_rc(x, y)
    map_col, map_row = col.astype(np.float32), row.astype(np.float32)
    values = _remap(image, map_col, map_row)
    if values.ndim == 2:  # cv2 drops a single channel axis
        values = values[..., None]
    observed = _remap(obs, map_col, map_row) >= _OBSERVED_MIN
    return np.moveaxis(values, -1, 0), observed


def extract_patches(bev: BEVMap, poses: np.ndarray,
                    margin: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Heading-aligned patches of the BEV at vehicle poses.

    poses: (N, 3) [x m, y m, θ rad] (or a single (3,) pose).
    Returns patches (N, 6, 22, 7) float32 and observed (N, 22, 7) bool — or
    (6, 22, 7) and (22, 7) for a single pose. Row 0 = ahead, column 0 = left.
    ``margin``: cells of context on every side (:func:`patch_offsets`), patches
    (N, 6, 22 + 2m, 7 + 2m).
    """
    poses = np.asarray(poses, dtype=np.float64)
    single = poses.ndim == 1
    if single:
        poses = poses[None]
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"poses must have shape (N, 3) [x, y, theta], got {poses.shape}")
    if not np.isfinite(poses).all():
        raise ValueError("poses contain non-finite values")
    if bev.grid.resolution != PATCH_RES:
        raise ValueError(f"patches are defined on a {PATCH_RES} m BEV grid, "
                         f"got {bev.grid.resolution} m")
    n = len(poses)
    image, obs = _bev_image(bev)
    offsets = patch_offsets(margin=margin)
    rows, cols = offsets.shape[:2]
    offsets = offsets.reshape(rows * cols, 2)
    patches = np.empty((n, N_CHANNELS, rows, cols), dtype=np.float32)
    observed = np.empty((n, rows, cols), dtype=bool)
    chunk = max(_CHUNK * PATCH_ROWS * PATCH_COLS // (rows * cols), 1)  # cv2: sides < 32767
    for start in range(0, n, chunk):
        stop = min(start + chunk, n)
        x, y = body_to_world(poses[start:stop], offsets)  # (n_chunk, rows · cols)
        values, seen = _sample_image(image, obs, bev.grid, x, y)  # (6, n_chunk, rows · cols)
        patches[start:stop] = np.moveaxis(values, 0, 1).reshape(
            stop - start, N_CHANNELS, rows, cols)
        observed[start:stop] = seen.reshape(stop - start, rows, cols)
    if single:
        return patches[0], observed[0]
    return patches, observed


@dataclass(frozen=True)
class RotationTransform:
    """Geometry of a map rotated so that heading θ points up.

    Rotated pixel (row v, column u) — integers at pixel centres — lies at the
    body-frame offset forward = −(v − center)·res, left = −(u − center)·res from
    the pivot ``pivot_xy`` for a vehicle with heading ``theta``: up = θ, column
    index grows toward the vehicle's right, exactly like a patch.
    shape: (D, D) of the rotated image.
    """

    grid: GridSpec
    theta: float
    pivot_xy: tuple[float, float]
    center: int
    shape: tuple[int, int]

    def rotated_to_xy(self, row, col) -> tuple[np.ndarray, np.ndarray]:
        """World (x, y) [m] of (continuous) rotated pixel coordinates (row, col)."""
        forward = -(np.asarray(row, dtype=np.float64) - self.center) * self.grid.resolution
        left = -(np.asarray(col, dtype=np.float64) - self.center) * self.grid.resolution
        c, s = np.cos(self.theta), np.sin(self.theta)
        px, py = self.pivot_xy
        return px + forward * c - left * s, py + forward * s + left * c

    def xy_to_rotated(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Continuous rotated pixel coordinates (row, col) of world points."""
        dx = np.asarray(x, dtype=np.float64) - self.pivot_xy[0]
        dy = np.asarray(y, dtype=np.float64) - self.pivot_xy[1]
        c, s = np.cos(self.theta), np.sin(self.theta)
        forward, left = dx * c + dy * s, -dx * s + dy * c
        return (self.center - forward / self.grid.resolution,
                self.center - left / self.grid.resolution)

    def window_center(self, top_row, left_col) -> tuple[np.ndarray, np.ndarray]:
        """Rotated (row, col) of the vehicle position of the 22 × 7 window whose
        top-left pixel is (top_row, left_col): (top_row + 10.5, left_col + 3)."""
        return np.asarray(top_row) + _ROW_CENTER, np.asarray(left_col) + _COL_CENTER

    def window_pose(self, top_row, left_col) -> np.ndarray:
        """(..., 3) world poses [x, y, θ] whose :func:`extract_patches` patch equals
        the window with top-left pixel (top_row, left_col)."""
        x, y = self.rotated_to_xy(*self.window_center(top_row, left_col))
        return np.stack(np.broadcast_arrays(x, y, np.full(np.shape(x), self.theta)), axis=-1)


class RotatedMap(NamedTuple):
    """Result of :func:`rotate_map`: channels (6, D, D) float32, observed (D, D)
    bool and the :class:`RotationTransform`. Unpacks as a tuple."""

    channels: np.ndarray
    observed: np.ndarray
    transform: RotationTransform


def rotated_size(grid: GridSpec) -> tuple[int, int]:
    """(D, center): side of the square rotated image [px] and the pivot's pixel.

    D is large enough, for every θ, to hold the whole map plus a margin so that a
    22 × 7 window centred on any map cell lies inside the image.
    """
    h, w = grid.shape
    half_map = np.hypot(h / 2.0 + 1.0, w / 2.0 + 1.0)
    half_patch = np.hypot(PATCH_ROWS / 2.0, PATCH_COLS / 2.0)
    center = int(np.ceil(half_map + half_patch)) + 1
    return 2 * center + 1, center


def rotation_transform(grid: GridSpec, theta: float) -> RotationTransform:
    """The :class:`RotationTransform` of :func:`rotate_map` for ``grid`` and heading θ [rad]:
    a D × D image (:func:`rotated_size`) pivoted on the centre of cell (H // 2, W // 2)."""
    d, center = rotated_size(grid)
    h, w = grid.shape
    pivot = tuple(float(v) for v in grid.cell_to_xy(h // 2, w // 2))
    return RotationTransform(grid, float(theta), pivot, center, (d, d))


def rotated_pixels(bev: BEVMap, transform: RotationTransform, rows: slice,
                   cols: slice) -> tuple[np.ndarray, np.ndarray]:
    """The pixels ``[rows, cols]`` (unit-step slices) of the rotated map, sampled from
    ``bev``: channels (6, r, c) float32 and observed (r, c) bool, equal to the same
    pixels of :func:`rotate_map` (used to refresh only part of a rotated map)."""
    r, c = np.mgrid[rows, cols]
    x, y = transform.rotated_to_xy(r, c)
    return sample_bev(bev, x, y)


def rotate_map(bev: BEVMap, theta: float) -> RotatedMap:
    """Resample the whole BEV so that heading θ [rad] points up (toward row 0).

    The rotated image is D × D (:func:`rotated_size`, the same D for every θ),
    pivoted on the centre of cell (H // 2, W // 2): for θ a multiple of π/2 its
    pixels coincide with BEV cells and the rotation is an exact permutation.
    ``sliding_windows(rotated.channels)[:, a, b]`` equals
    ``extract_patches(bev, rotated.transform.window_pose(a, b))``.
    This is the paper's "rotate the map by −θ_k" (Costmap Construction).
    """
    if bev.grid.resolution != PATCH_RES:
        raise ValueError(f"patches are defined on a {PATCH_RES} m BEV grid, "
                         f"got {bev.grid.resolution} m")
    transform = rotation_transform(bev.grid, theta)
    d = transform.shape[0]
    channels, observed = rotated_pixels(bev, transform, slice(0, d), slice(0, d))
    return RotatedMap(channels, observed, transform)


def sliding_windows(rotated: np.ndarray) -> np.ndarray:
    """All 22 × 7 windows of a rotated (C, D, D) array, as a read-only view.

    Returns (C, D − 21, D − 6, 22, 7): element [:, a, b] is the window whose
    top-left pixel is (a, b), i.e. the patch at ``transform.window_pose(a, b)``.
    """
    return np.lib.stride_tricks.sliding_window_view(rotated, (PATCH_ROWS, PATCH_COLS),
                                                    axis=(-2, -1))


def window_counts(mask: np.ndarray) -> np.ndarray:
    """(D − 21, D − 6) number of True pixels under each 22 × 7 window of a (D, D) mask,
    indexed like :func:`sliding_windows` (by the window's top-left pixel); exact, from an
    integral image (``sliding_windows(mask).any(axis=(-2, -1))`` is ``> 0`` of it, ~50×
    slower)."""
    s = cv2.integral(mask.astype(np.uint8))  # (D + 1, D + 1) int32
    return (s[PATCH_ROWS:, PATCH_COLS:] - s[:-PATCH_ROWS, PATCH_COLS:]
            - s[PATCH_ROWS:, :-PATCH_COLS] + s[:-PATCH_ROWS, :-PATCH_COLS])


def unrotate_map(layers: np.ndarray, transform: RotationTransform,
                 cells: tuple[slice, slice] | None = None) -> np.ndarray:
    """Bring per-pixel values of the rotated frame back onto the BEV grid.

    layers: (C, D, D) or (D, D) in rotated pixel coordinates. Each BEV cell centre is
    looked up at its rotated position (bilinear). Returns (C, H, W) or (H, W) float32;
    cells that fall outside the rotated image get 0 (cannot happen for maps rotated by
    :func:`rotate_map`).
    cells: only the BEV cells ``[rows, cols]`` (unit-step slices): returns (C, r, c),
    equal to that part of the whole map's result.
    """
    layers = np.asarray(layers, dtype=np.float32)
    squeeze = layers.ndim == 2
    if squeeze:
        layers = layers[None]
    if layers.shape[-2:] != transform.shape:
        raise ValueError(f"layers must be (C, {transform.shape[0]}, {transform.shape[1]}), "
                         f"got {layers.shape}")
    if cells is None:
        x, y = transform.grid.cell_centers()
    else:
        x, y = transform.grid.cell_to_xy(*np.mgrid[cells[0], cells[1]])
    row, col = transform.xy_to_rotated(x, y)
    out = np.empty((layers.shape[0], *x.shape), dtype=np.float32)
    for k, layer in enumerate(layers):
        out[k] = cv2.remap(np.ascontiguousarray(layer), col.astype(np.float32),
                           row.astype(np.float32), interpolation=cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return out[0] if squeeze else out
