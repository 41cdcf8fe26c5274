"""Everything a planner needs on one world, in one object."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dgt_lib.core.geometry import GridSpec, nearest_heading_bin
from dgt_lib.mapping.methods import check_method
from dgt_lib.perception.bev import BEVMap


@dataclass
class WorldMaps:
    """Everything a planner needs on one world: the BEV, occupancy, τ_s and costmaps."""

    world: str
    bev: BEVMap
    occupancy: np.ndarray
    tau_s: float
    costmaps: dict[tuple[str, str], np.ndarray]  # (method, vehicle) → (K, H, W)

    @property
    def grid(self) -> GridSpec:
        return self.bev.grid

    def costmap(self, method: str, vehicle: str) -> np.ndarray:
        check_method(method, vehicle)
        if (method, vehicle) not in self.costmaps:
            raise KeyError(f"{method} costmap of {vehicle} was not computed for {self.world}; "
                           f"have: {sorted(self.costmaps)}")
        return self.costmaps[(method, vehicle)]

    def cost_at(self, method: str, vehicle: str, x, y, heading) -> np.ndarray:
        """C of ``method`` for ``vehicle`` at points x, y [m] travelled at ``heading`` [rad]:
        the cell containing each point (clamped to the map), the layer of the nearest
        heading θ_k (paper: Directional Cost Lookup). Arrays broadcast; returns float64."""
        cost = self.costmap(method, vehicle)
        r, c = self.grid.xy_to_cell(np.asarray(x, np.float64), np.asarray(y, np.float64))
        r = np.clip(r, 0, cost.shape[1] - 1)
        c = np.clip(c, 0, cost.shape[2] - 1)
        k = nearest_heading_bin(np.asarray(heading, np.float64), cost.shape[0])
        return cost[k, r, c].astype(np.float64)
