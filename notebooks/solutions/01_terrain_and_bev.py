"""Reference solution to notebook 01's exercise: the plane through one cell's points."""

import numpy as np


def cell_plane(points):
    """(h, a, b) of the plane z = h + a·x + b·y fitted to one cell's points.

    points: (N, 3) float [m], columns x, y (offsets from the cell centre) and z.
    Returns h [m], a [m/m], b [m/m]: least squares on the columns [1, x, y], so h is the
    plane's height at the centre (x = y = 0), not the points' mean height."""
    points = np.asarray(points, dtype=np.float64)
    design = np.column_stack([np.ones(len(points)), points[:, 0], points[:, 1]])
    h, a, b = np.linalg.lstsq(design, points[:, 2], rcond=None)[0]
    return float(h), float(a), float(b)
