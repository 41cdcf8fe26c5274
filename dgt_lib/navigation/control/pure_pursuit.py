"""Pure-pursuit path tracking: the simple tracker of the scripted drives (notebook 01, the
physical-premise tests); closed-loop trials use MPPI (:mod:`dgt_lib.navigation.control.mppi`)."""

from __future__ import annotations

import math

import numpy as np

from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.world.simulator import VehicleState


class PurePursuit:
    """Pure-pursuit steering along a (M, 2) waypoint path [m]: aim at the path point
    ``lookahead_m`` beyond the one nearest the rear axle and steer
    δ = atan(2L·sin α / l_d) (α: bearing of that point, l_d: its distance)."""

    def __init__(self, path_xy: np.ndarray, vehicle: VehicleSpec, lookahead_m: float = 6.0,
                 spacing_m: float = 0.25):
        path = np.asarray(path_xy, np.float64)
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
        s = np.arange(0.0, cum[-1] + spacing_m, spacing_m)
        self.dense = np.stack([np.interp(s, cum, path[:, 0]), np.interp(s, cum, path[:, 1])], 1)
        self.vehicle = vehicle
        self.ahead = max(1, int(round(lookahead_m / spacing_m)))
        self._i = 0

    def __call__(self, state: VehicleState) -> float:
        """Normalised steer ∈ [−1, 1] for the current state."""
        v = self.vehicle
        c, s = math.cos(state.yaw), math.sin(state.yaw)
        rear = state.position[:2] - 0.5 * v.wheelbase_m * np.array([c, s])
        # Search near the last match only, so a path that loops back is followed in order.
        lo, hi = self._i, min(len(self.dense), self._i + 8 * self.ahead)
        self._i = lo + int(np.argmin(np.linalg.norm(self.dense[lo:hi] - rear, axis=1)))
        dx, dy = self.dense[min(len(self.dense) - 1, self._i + self.ahead)] - rear
        alpha = math.atan2(dy, dx) - state.yaw
        delta = math.atan2(2 * v.wheelbase_m * math.sin(alpha), max(math.hypot(dx, dy), 1e-3))
        return float(np.clip(delta / v.max_steer_rad, -1.0, 1.0))
