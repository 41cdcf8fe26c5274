"""Reference solution to notebook 08's exercise: hazard metres on a query's straight line."""

import numpy as np


def hazard_length(mask, origin_xy, resolution_m, start, goal):
    """Metres of the straight segment start → goal on the True cells of ``mask`` (H, W).

    origin_xy: (x0, y0) [m], the corner of cell (0, 0); resolution_m: Δ [m];
    start: (x, y) or (x, y, yaw), goal: (x, y) [m]."""
    (sx, sy), (gx, gy) = start[:2], goal[:2]
    d = float(np.hypot(gx - sx, gy - sy))
    n = max(2, int(np.ceil(d / (resolution_m / 2))) + 1)
    t = np.linspace(0.0, 1.0, n)
    col = np.floor((sx + t * (gx - sx) - origin_xy[0]) / resolution_m).astype(int)
    row = np.floor((sy + t * (gy - sy) - origin_xy[1]) / resolution_m).astype(int)
    on_map = (row >= 0) & (row < mask.shape[0]) & (col >= 0) & (col < mask.shape[1])
    hazard = np.zeros(n, bool)
    hazard[on_map] = mask[row[on_map], col[on_map]]
    return d * hazard.mean()
