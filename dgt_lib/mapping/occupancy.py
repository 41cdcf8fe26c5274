"""The occupancy map and its threshold τ_s (paper: Occupancy Map).

The planner checks collisions on an occupancy map decoupled from the costmap:

    occ(i, j) = 1  if ‖∇H̄(i, j)‖ > τ_s,   2 if unobserved,   else 0

τ_s is "the smallest threshold that eliminates no terrain traversable in at least
one direction": here the steepest BEV gradient on the kit worlds' known-traversable
routes (:func:`traversed_gradients`), times a small margin (:func:`select_tau_s`).
"""

from __future__ import annotations

import numpy as np

from dgt_lib.perception.bev import GRADIENT, BEVMap
from dgt_lib.world.worlds import World, polyline_distance

FREE, OCCUPIED, UNOBSERVED = 0, 1, 2
"""Occupancy values; unobserved cells count as occupied for collision checks."""

TAU_S_ROUTE_CORE_M = 1.5
"""Cells within this distance of a known-traversable route's centre line define τ_s [m]."""


def occupancy_map(bev: BEVMap, tau_s: float) -> np.ndarray:
    """occ = 1 where ‖∇H̄‖ > τ_s, 2 where unobserved, else 0 (paper eq. Occupancy Map).

    Returns (H, W) uint8. Unobserved cells are occupied for collision checks.
    """
    occ = np.where(bev.channels[GRADIENT] > tau_s, OCCUPIED, FREE).astype(np.uint8)
    occ[~bev.observed] = UNOBSERVED
    return occ


def select_tau_s(traversed_gradients: np.ndarray, margin: float = 1.05) -> float:
    """τ_s by the paper's rule: the smallest threshold that eliminates no terrain that
    was traversed in at least one direction.

    traversed_gradients: ‖∇H̄‖ [m/m] of the BEV cells that some vehicle drove over
    successfully (any direction) — e.g. under the runs of the data collection, or
    along the known feasible crossings of a world. τ_s is their maximum, times a
    small ``margin`` so that those cells stay strictly below it.
    """
    g = np.asarray(traversed_gradients, dtype=np.float64)
    g = g[np.isfinite(g)]
    if g.size == 0:
        raise ValueError("select_tau_s needs at least one traversed cell")
    return float(g.max() * margin)


def traversed_gradients(world: World, bev: BEVMap,
                        core_m: float = TAU_S_ROUTE_CORE_M) -> np.ndarray:
    """‖∇H̄‖ [m/m] of the observed BEV cells within ``core_m`` of a world's
    known-traversable route centre lines (``world.routes``): the hill's Routes A and B
    (B is steep but traversable downhill) and the ridge's crossings (the sharp one is
    traversable by the jeep). Returns a 1-D array."""
    x, y = bev.grid.cell_centers()
    points = np.stack([x[bev.observed], y[bev.observed]], axis=1)
    grads = bev.channels[GRADIENT][bev.observed]
    near = np.zeros(len(points), bool)
    for route in world.routes.values():
        near |= polyline_distance(points, np.asarray(route, float))[0] <= core_m
    return grads[near]
