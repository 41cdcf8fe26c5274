"""Per-cell least-squares planes of the BEV (paper: Global Map — H̄ and σ_H per cell).

A cell's H̄ is the height at its centre of the plane z = h + a·x + b·y fitted to the points
that fell in it (x, y their offsets from the cell centre), from additive moment sums
(:data:`MOMENTS`), so that accumulators of survey and onboard frames merge exactly. Where a
cell's own points cannot fix a slope (one or two points, or all on a line), the slope of
its 3×3 neighbourhood is used, trusted only as far as the neighbourhood is itself a plane
(:data:`PLANAR_SCALE_M`). :class:`~dgt_lib.perception.bev.BEVAccumulator` keeps the sums;
this module turns them into planes.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

MOMENTS: tuple[str, ...] = ("r", "g", "b", "x", "y", "z", "xx", "xy", "yy", "xz", "yz", "zz")
"""The per-cell sums a :class:`BEVAccumulator` keeps besides the point count: Σ colour, then
Σ of x, y (a point's offset from its cell's centre [m]), z (its height [m]) and their
products — the moments a least-squares plane and the height spread need."""
_X, _Y, _Z, _XX, _XY, _YY, _XZ, _YZ, _ZZ = range(3, 12)

SLOPE_PRIOR_FRACTION = 0.1
"""A cell's plane slope is pulled towards its 3×3 neighbourhood's with the weight of a
spread of offsets of (0.1·cell size)² [m²] (see :func:`fit_cell_planes`)."""

_NEIGHBOURHOOD_PRIOR_FRACTION = 0.01
"""Likewise, the 3×3 neighbourhood's slope is pulled towards 0 with (0.01·cell size)²,
so that a neighbourhood whose points do not span a plane gets a level one."""

PLANAR_SCALE_M = 0.1
"""The 3×3 neighbourhood's slope is trusted as far as its points lie on a plane: it is
scaled by σ₀²/(σ₀² + s₀²), s₀ their rms residual about it [m] and σ₀ this scale [m]. Next
to a tree crown or a cliff (s₀ of metres) the neighbourhood says nothing about the
ground's slope; used anyway, it moved a cell's H̄ by up to 0.9 m."""


def _centred_moments(count: np.ndarray, sums: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per-point means and central moments of the points in each cell (0 where empty).

    count: (...) points; sums: (8 or 9, ...) Σx, Σy, Σz, Σxx, Σxy, Σyy, Σxz, Σyz[, Σzz].
    Returns mx, my, mz [m], cxx, cxy, cyy, cxz, cyz[, czz] [m²], each shaped like count.
    """
    n = np.maximum(count, 1).astype(np.float64)
    mx, my, mz = sums[0] / n, sums[1] / n, sums[2] / n
    out = [mx, my, mz, sums[3] / n - mx * mx, sums[4] / n - mx * my, sums[5] / n - my * my,
           sums[6] / n - mx * mz, sums[7] / n - my * mz]
    if len(sums) > 8:
        out.append(sums[8] / n - mz * mz)
    return tuple(out)


def _ridge_slopes(cxx: np.ndarray, cxy: np.ndarray, cyy: np.ndarray, cxz: np.ndarray,
                  cyz: np.ndarray, lam: float, prior: tuple = (0.0, 0.0)
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The slope (a, b) [m/m] minimising mean (z − h − a·x − b·y)² + λ·|(a, b) − prior|²
    (h free) from the central moments: (C + λI)(a, b)ᵀ = (cxz, cyz)ᵀ + λ·prior, where C
    is the offsets' covariance. λ > 0 [m²] keeps it solvable where C is singular."""
    a11, a22 = cxx + lam, cyy + lam
    det = a11 * a22 - cxy * cxy  # ≥ λ² > 0: C is positive semi-definite
    rx, ry = cxz + lam * prior[0], cyz + lam * prior[1]
    return (a22 * rx - cxy * ry) / det, (a11 * ry - cxy * rx) / det


def _shift_pass(m: np.ndarray, axis: int, resolution: float) -> np.ndarray:
    """One axis of :func:`_neighbourhood_sums`: per cell, the sums of it and its two
    neighbours along ``axis`` (1: rows, y; 2: columns, x), each with the coordinate u along
    that axis taken from this cell's centre: a neighbour k = ±1 adds its sums with
    u → u + k·res, i.e. Σu += k·res·n, Σu² += 2k·res·Σu + res²·n, Σuv += k·res·Σv."""
    u, v, uu = (2, 1, 6) if axis == 1 else (1, 2, 4)  # rows: n, x, y, z, xx, xy, yy, xz, yz, zz
    pad = [(0, 0)] * 3
    pad[axis] = (1, 1)
    padded = np.pad(m, pad)
    take = [slice(None)] * 3
    take[axis] = slice(0, -2)
    lo = padded[tuple(take)]  # the neighbour at k = −1
    take[axis] = slice(2, None)
    hi = padded[tuple(take)]  # k = +1
    out = lo + hi
    out += m
    out[u] += resolution * (hi[0] - lo[0])
    out[uu] += 2 * resolution * (hi[u] - lo[u]) + resolution**2 * (hi[0] + lo[0])
    out[5] += resolution * (hi[v] - lo[v])  # Σxy
    out[7 if u == 1 else 8] += resolution * (hi[3] - lo[3])  # Σxz or Σyz
    return out


def _mean_sq_residual(a: np.ndarray, b: np.ndarray, *central: np.ndarray) -> np.ndarray:
    """The mean (z − h − a·x − b·y)² [m²] of points about the plane of slope (a, b) through
    their centroid (h = z̄ − a·x̄ − b·ȳ), from their central moments ``central`` = cxx, cxy,
    cyy, cxz, cyz, czz; ≥ 0."""
    cxx, cxy, cyy, cxz, cyz, czz = central
    r = czz - 2 * (a * cxz + b * cyz) + a * a * cxx + 2 * a * b * cxy + b * b * cyy
    return np.maximum(r, 0.0)


def _neighbourhood_sums(count: np.ndarray, sums: np.ndarray, resolution: float) -> np.ndarray:
    """Per cell, the moments of all points in its 3×3 neighbourhood, with offsets taken
    from *its* centre: a neighbour (r+i, c+j) adds its sums with x → x + j·res, y → y + i·res.

    count: (H, W); sums: (9, H, W) Σx, Σy, Σz, Σxx, Σxy, Σyy, Σxz, Σyz, Σzz. Returns
    (10, H, W): n, then the same nine sums (beyond the grid's border counts as empty).
    Separable: a pass along the columns, then one along the rows (:func:`_shift_pass`).
    """
    raw = np.concatenate([count[None].astype(np.float64), sums])
    return _shift_pass(_shift_pass(raw, 2, resolution), 1, resolution)


class CellPlanes(NamedTuple):
    """Per cell, the plane z ≈ height + slope_x·x + slope_y·y through its points, x, y
    their offsets from the cell centre: (H, W) float64 arrays, 0 where unobserved."""

    height: np.ndarray
    """[m] the plane at the cell centre (= its mean over the cell)."""
    slope_x: np.ndarray
    """∂z/∂x [m/m]."""
    slope_y: np.ndarray
    """∂z/∂y [m/m]."""
    residual_var: np.ndarray
    """[m²] the points' mean squared residual about the plane."""


def fit_cell_planes(count: np.ndarray, sums: np.ndarray, resolution: float) -> CellPlanes:
    """A least-squares plane z ≈ h + a·x + b·y per cell, x, y offsets from its centre [m].

    count: (H, W) points per cell; sums: (9, H, W) Σx, Σy, Σz, Σxx, Σxy, Σyy, Σxz, Σyz,
    Σzz of the points (:data:`MOMENTS` from ``x`` on). A cell's own points fix the plane
    where they span it; where they do not (1–2 points, or all on one line — common, as a
    survey pixel covers ~0.2 m of ground) its slope comes from the 3×3 neighbourhood:

        (a₀, b₀) = argmin Σ_{3×3} (z − h − a·x − b·y)² / n + λ₀·(a² + b²),
        (a, b)   = argmin Σ_cell  (z − h − a·x − b·y)² / n + λ·|(a, b) − (a₀, b₀)|²,
        h = z̄ − a·x̄ − b·ȳ,

    with λ = (0.1·res)² (:data:`SLOPE_PRIOR_FRACTION`; offsets spread evenly over a cell
    have variance res²/12 = 8.3·λ, so a well-sampled cell keeps its own slope) and
    λ₀ = (0.01·res)². The neighbourhood's slope is then scaled by σ₀²/(σ₀² + s₀²), s₀² the
    mean squared residual of its points about their plane, σ₀ = :data:`PLANAR_SCALE_M`:
    where the neighbourhood is no plane (a crown or cliff beside the cell) a sparsely
    sampled cell falls back towards its points' mean. An isolated cell with one point gets
    its height, level.

    Returns :class:`CellPlanes` (h, a, b and s², the points' mean squared residual about
    the plane), 0 where a cell is empty.
    """
    own = _centred_moments(count, sums)
    near = _neighbourhood_sums(count, sums, resolution)
    _, _, _, pxx, pxy, pyy, pxz, pyz, pzz = _centred_moments(near[0], near[1:])
    a0, b0 = _ridge_slopes(pxx, pxy, pyy, pxz, pyz,
                           (_NEIGHBOURHOOD_PRIOR_FRACTION * resolution) ** 2)
    s0 = _mean_sq_residual(a0, b0, pxx, pxy, pyy, pxz, pyz, pzz)
    trust = PLANAR_SCALE_M**2 / (PLANAR_SCALE_M**2 + s0)
    mx, my, mz, cxx, cxy, cyy, cxz, cyz, czz = own
    a, b = _ridge_slopes(cxx, cxy, cyy, cxz, cyz, (SLOPE_PRIOR_FRACTION * resolution) ** 2,
                         (trust * a0, trust * b0))
    height = mz - a * mx - b * my
    resid = _mean_sq_residual(a, b, cxx, cxy, cyy, cxz, cyz, czz)
    seen = count > 0
    return CellPlanes(*(np.where(seen, v, 0.0) for v in (height, a, b, resid)))
