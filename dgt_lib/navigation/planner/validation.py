"""Validation of the planner's maps, and of a query against the world alone
(:func:`check_query_on_world`, before any map is built). The planner's settings are
checked against the one table of rules (:mod:`dgt_lib.core.constraints`)."""

from __future__ import annotations

import math

import numpy as np

from dgt_lib.core.geometry import GridSpec
from dgt_lib.core.vehicle_spec import VehicleSpec, footprint_circles
from dgt_lib.navigation.planner.result import InvalidQueryError
from dgt_lib.world.worlds import World


def check_maps(costmap: np.ndarray, occupancy: np.ndarray, grid: GridSpec) -> None:
    """Raise ValueError unless costmap is (K, H, W) in [0, 1] and occupancy (H, W) in
    {0, 1, 2}, (H, W) = ``grid.shape``."""
    if costmap.ndim != 3 or costmap.shape[1:] != grid.shape:
        raise ValueError(
            f"costmap must be (K, H, W) with (H, W) = {grid.shape}, got {costmap.shape}"
        )
    if not (costmap.min() >= 0 and costmap.max() <= 1):  # false for NaN and ±∞ too
        raise ValueError("costmap values must be finite and in [0, 1]")
    if occupancy.shape != grid.shape:
        raise ValueError(f"occupancy must be (H, W) = {grid.shape}, got {occupancy.shape}")
    if not (occupancy.dtype == np.uint8 and occupancy.max() <= 2
            or np.isin(occupancy, (0, 1, 2)).all()):
        raise ValueError("occupancy values must be 0 (free), 1 (occupied) or 2 (unobserved)")


def check_query_on_world(world: World, spec: VehicleSpec, start, goal) -> None:
    """Raise :class:`InvalidQueryError` for a query that no map of ``world`` can make
    valid, judged from the world alone (no BEV, costmap or model: milliseconds).

    start (x, y, θ) [m, m, rad], goal (x, y) or (x, y, θ). Rejected: non-finite
    numbers; a start or goal off the map (outside ``world.extent``); a start whose
    footprint circles (the planner's, :func:`footprint_circles`) leave the map; a start
    whose length × width rectangle overlaps a tree trunk; a goal inside a trunk.

    Each is a case :meth:`HybridAStar.plan` also rejects on the world's maps (off the
    map, footprint circles off the map or near the unobserved cells beyond the terrain,
    a trunk's occupied ring), so this adds no rule of its own; slopes, steps and
    unobserved terrain need the occupancy map (‖∇H̄‖ > τ_s) and are left to it.
    """
    start = np.asarray(start, dtype=np.float64).ravel()
    goal = np.asarray(goal, dtype=np.float64).ravel()
    if start.shape != (3,) or not np.all(np.isfinite(start)):
        raise InvalidQueryError(f"start must be a finite (x, y, θ), got {start.tolist()}")
    if goal.shape not in ((2,), (3,)) or not np.all(np.isfinite(goal)):
        raise InvalidQueryError(f"goal must be a finite (x, y) or (x, y, θ), got {goal.tolist()}")
    x0, x1, y0, y1 = world.extent
    extent = f"x {x0:g} to {x1:g} m, y {y0:g} to {y1:g} m"
    for name, (x, y) in (("start", start[:2]), ("goal", goal[:2])):
        if not world.grid.contains(x, y):
            raise InvalidQueryError(f"{name} ({x:.2f}, {y:.2f}) m is off the map ({extent})")
    sx, sy, sth = start
    offsets, _ = footprint_circles(spec.length_m, spec.width_m)
    if not np.all(world.grid.contains(sx + offsets * math.cos(sth),
                                      sy + offsets * math.sin(sth))):
        raise InvalidQueryError(
            f"start pose ({sx:.2f}, {sy:.2f}, {sth:.2f}) is too close to the map edge: the "
            f"{spec.name}'s {spec.length_m:.2f} m long footprint leaves the map ({extent})")
    trees = np.asarray(world.trees, np.float64).reshape(-1, 4)
    hit = _trunks_under_rectangle(trees, start, spec.length_m, spec.width_m)
    if hit.size:
        tx, ty, tr = trees[hit[0], :3]
        raise InvalidQueryError(
            f"start pose ({sx:.2f}, {sy:.2f}, {sth:.2f}) is on a tree: the {spec.name}'s "
            f"{spec.length_m:.2f}×{spec.width_m:.2f} m footprint overlaps the trunk at "
            f"({tx:.2f}, {ty:.2f}) m (radius {tr:.2f} m)")
    inside = np.flatnonzero(np.hypot(trees[:, 0] - goal[0], trees[:, 1] - goal[1]) < trees[:, 2])
    if inside.size:
        tx, ty, tr = trees[inside[0], :3]
        raise InvalidQueryError(f"goal ({goal[0]:.2f}, {goal[1]:.2f}) m is inside the tree trunk "
                                f"at ({tx:.2f}, {ty:.2f}) m (radius {tr:.2f} m)")


def _trunks_under_rectangle(trees: np.ndarray, pose: np.ndarray, length_m: float,
                            width_m: float) -> np.ndarray:
    """Indices of the trunks (rows x, y, radius, … of ``trees`` [m]) whose disc overlaps
    the length × width rectangle centred on ``pose`` (x, y, θ) [m, m, rad]."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dx, dy = trees[:, 0] - pose[0], trees[:, 1] - pose[1]
    along, across = dx * c + dy * s, -dx * s + dy * c  # trunk centres in the vehicle frame
    gap_along = np.maximum(np.abs(along) - 0.5 * length_m, 0.0)
    gap_across = np.maximum(np.abs(across) - 0.5 * width_m, 0.0)
    return np.flatnonzero(np.hypot(gap_along, gap_across) < trees[:, 2])
