"""The path MPPI tracks: the planner's path resampled, the robot's progress along it, and
the window of it the rollouts are scored against (paper: Controller Integration)."""

from __future__ import annotations

import math

import numpy as np

from dgt_lib.navigation.control.bicycle import resample_path


class ReferencePath:
    """A path ``(N, 3)`` of (x [m], y [m], yaw [rad]) resampled every ``spacing_m``; its
    last point is the goal. ``points`` ``(M, 3)``, arc length ``s`` ``(M,)`` [m],
    ``length_m``, unit ``tangent`` ``(M, 2)``. The progress search looks 2 m back and as
    far ahead as a rollout of ``horizon_m`` can reach (plus 2 m)."""

    def __init__(self, path: np.ndarray, spacing_m: float, horizon_m: float):
        pts, s = resample_path(path, spacing_m)
        self.points = pts
        self.s = s
        self.length_m = float(s[-1])
        tangent = np.gradient(pts[:, :2], axis=0)
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        self.tangent = tangent  # (M, 2) unit direction of travel along the points
        self.progress: int | None = None
        ds = s[1] - s[0]
        self._back = int(math.ceil(2.0 / ds))
        self._ahead = int(math.ceil((horizon_m + 2.0) / ds)) + 1

    def update_progress(self, x: float, y: float) -> int:
        """Index of the point nearest (x, y) [m], searched near the last one."""
        if self.progress is None:
            lo, hi = 0, len(self.points)
        else:
            lo = max(0, self.progress - self._back)
            hi = min(len(self.points), self.progress + self._ahead)
        d2 = (self.points[lo:hi, 0] - x) ** 2 + (self.points[lo:hi, 1] - y) ** 2
        self.progress = lo + int(np.argmin(d2))
        return self.progress

    def remaining_m(self, i: int) -> float:
        """Path length [m] from point ``i`` to the goal."""
        return self.length_m - float(self.s[i])

    def goal_relative(self, x0: float, y0: float) -> tuple[float, float]:
        """The goal's position [m] relative to (x0, y0)."""
        return self.points[-1, 0] - x0, self.points[-1, 1] - y0

    def window(self, i: int, x0: float, y0: float) -> tuple[np.ndarray, ...]:
        """The points around progress ``i``, float32 ``(M',)`` each: position relative to
        (x0, y0) (x, y) [m], unit tangent (x, y), arc length s [m] and yaw [rad]."""
        lo = max(0, i - self._back)
        hi = min(len(self.points), i + self._ahead)
        win = self.points[lo:hi]
        return ((win[:, 0] - x0).astype(np.float32), (win[:, 1] - y0).astype(np.float32),
                self.tangent[lo:hi, 0].astype(np.float32),
                self.tangent[lo:hi, 1].astype(np.float32),
                self.s[lo:hi].astype(np.float32), win[:, 2].astype(np.float32))
