"""Everything a planner needs on one world, in one object."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dgt_lib.core.geometry import GridSpec
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
