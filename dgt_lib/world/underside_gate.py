"""The simulator's per-step arithmetic, compiled: how close the vehicle's belly comes to
the terrain (the underside gate), and whether the state has blown up.

Box–heightfield collision tests cost more than the rest of a physics step, and a
vehicle's underside is clear of the ground most of the time, so :class:`~dgt_lib.world.
simulator.Simulator` lets the belly and bumpers collide with the terrain only while
the terrain may reach them. Deciding that runs every few physics steps; in numpy it
cost as much as a quarter of the simulator's time, compiled it costs about a
microsecond. The lookup is :meth:`~dgt_lib.world.worlds.World.height_at`'s bilinear
interpolation on the cell-centre grid, clamped at the border.
"""

from __future__ import annotations

import mujoco
import numpy as np
from numba import njit


@njit(cache=True)
def min_underside_gap(points: np.ndarray, rot: np.ndarray, pos: np.ndarray, z: np.ndarray,
                      x0: float, y0: float, inv_res: float) -> float:
    """Smallest height [m] of the underside sample ``points`` ((n, 3), chassis frame [m])
    above the terrain, for the chassis at ``pos`` ((3,) [m]) with rotation ``rot``
    ((9,) world_from_chassis, row-major as MuJoCo's ``xmat``). ``z``: (rows, cols)
    terrain heights [m] at cell centres; ``x0, y0``: the first cell centre [m];
    ``inv_res``: 1 / cell size [1/m]. Negative when a point is below the ground."""
    h, w = z.shape
    gap = np.inf
    for i in range(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        x = rot[0] * px + rot[1] * py + rot[2] * pz + pos[0]
        y = rot[3] * px + rot[4] * py + rot[5] * pz + pos[1]
        wz = rot[6] * px + rot[7] * py + rot[8] * pz + pos[2]
        col = min(max((x - x0) * inv_res, 0.0), w - 1.001)
        row = min(max((y - y0) * inv_res, 0.0), h - 1.001)
        c0, r0 = int(col), int(row)
        fc, fr = col - c0, row - r0
        top = z[r0, c0] + fc * (z[r0, c0 + 1] - z[r0, c0])
        bottom = z[r0 + 1, c0] + fc * (z[r0 + 1, c0 + 1] - z[r0 + 1, c0])
        g = wz - (top + fr * (bottom - top))
        if g < gap:
            gap = g
    return gap


DIVERGENCE_WARNINGS = np.array([int(getattr(mujoco.mjtWarning, f"mjWARN_BAD{q}"))
                                for q in ("QPOS", "QVEL", "QACC")])
"""MuJoCo's warnings that it met NaN or huge values (it then resets the state itself)."""


@njit(cache=True)
def diverged(qpos: np.ndarray, qvel: np.ndarray, warnings: np.ndarray) -> bool:
    """Whether the state has blown up: MuJoCo counted one of :data:`DIVERGENCE_WARNINGS`
    (``warnings``: its counts), or a coordinate or velocity is not a finite number after
    the last step (MuJoCo checks them before one). Compiled: in numpy these checks cost ten
    times as long on arrays this small."""
    return (warnings[DIVERGENCE_WARNINGS] > 0).any() or not (
        np.isfinite(qpos).all() and np.isfinite(qvel).all())
