"""What one map gives the search, built once per map (:class:`PlannerMaps`): the footprint's
blocked cells, the directional costmap, the travel-direction layer table and the 2D
cost-to-go. Both searches (:mod:`.search`, :mod:`.compiled_search`) read only this."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from dgt_lib.core.config import PlannerConfig
from dgt_lib.core.geometry import GridSpec
from dgt_lib.core.vehicle_spec import footprint_circles
from dgt_lib.navigation.planner.collision import BlockedMap
from dgt_lib.navigation.planner.heuristics import CostToGo
from dgt_lib.navigation.planner.primitives import PrimitiveSet, travel_bin_table


class Query(NamedTuple):
    """One checked query: start (sx, sy, sth) [m, m, rad, θ wrapped], goal point (gx, gy)
    [m] and goal heading gth [rad] (None: any heading)."""

    sx: float
    sy: float
    sth: float
    gx: float
    gy: float
    gth: float | None


class CompiledMaps(NamedTuple):
    """The per-map arrays of the compiled search: ``blocked`` the padded blocked map,
    flat (:attr:`BlockedMap.flat`); ``cost`` the (K·H·W,) costmap; ``bin_table`` the
    flat layer table of :func:`.primitives.travel_bin_table`."""

    blocked: np.ndarray
    cost: np.ndarray
    bin_table: np.ndarray


class PlannerMaps:
    """One map's planning data for one vehicle.

    costmap: (K, H, W) float64 in [0, 1] (layer k = heading 2πk/K); occupancy: (H, W)
    uint8; grid: their :class:`GridSpec`; min_turn_radius_m [m]; footprint (length_m,
    width_m); cfg: the :class:`PlannerConfig`.

    Attributes: ``blocked`` (:class:`BlockedMap`), ``cost_flat`` (K·H·W,), ``bin_table``
    and ``bin_reach`` (the layer of every cell move one primitive can make),
    ``substep_m`` the actual sub-step spacing Δ ≤ ``cfg.substep_m`` [m], ``cost_to_go``
    (:class:`CostToGo`), ``circle_offsets`` [m] and ``circle_radius_m``, ``compiled`` the
    arrays the compiled search reads (:class:`CompiledMaps`).
    """

    def __init__(self, costmap: np.ndarray, occupancy: np.ndarray, grid: GridSpec, *,
                 min_turn_radius_m: float, footprint: tuple[float, float],
                 cfg: PlannerConfig):
        self.cfg, self.grid = cfg, grid
        self.n_headings = costmap.shape[0]
        self.min_turn_radius_m = float(min_turn_radius_m)
        self.footprint = (float(footprint[0]), float(footprint[1]))
        self.circle_offsets, self.circle_radius_m = footprint_circles(*self.footprint)
        self.costmap = np.ascontiguousarray(costmap, dtype=np.float64)
        self.cost_flat = self.costmap.ravel()
        self.occupancy = occupancy
        self.blocked = BlockedMap(
            occupancy, grid, self.circle_offsets, self.circle_radius_m,
            reach_m=cfg.step_m + float(np.abs(self.circle_offsets).max()),
            substeps=math.ceil(cfg.step_m / cfg.substep_m),
        )
        self.bin_table, self.bin_reach = travel_bin_table(
            cfg.step_m, grid.resolution, self.n_headings)
        self.substep_m = cfg.step_m / math.ceil(cfg.step_m / cfg.substep_m)
        self.cost_to_go = CostToGo(
            self.costmap, self.blocked.blocked, self.blocked.occupied_distance, grid, cfg,
            clearance_m=self.blocked.clearance_m, min_turn_radius_m=self.min_turn_radius_m,
            substep_m=self.substep_m,
        )
        self.compiled = CompiledMaps(self.blocked.flat, self.cost_flat,
                                     np.asarray(self.bin_table, dtype=np.int64))

    def primitives(self, start_heading: float) -> PrimitiveSet:
        """The arc primitives of a query starting at heading ``start_heading`` [rad]."""
        cfg = self.cfg
        return PrimitiveSet(
            start_heading, step_m=cfg.step_m, min_turn_radius_m=self.min_turn_radius_m,
            substep_m=cfg.substep_m, circle_offsets=self.circle_offsets,
            resolution=self.grid.resolution, theta_bins=cfg.theta_bins,
            n_headings=self.n_headings, origin_xy=self.grid.origin_xy,
        )
