"""The RGB-D frame contract between the simulator (producer) and the BEV map (consumer).

Camera frame convention (MuJoCo / OpenGL): the camera looks along its −z axis,
+x points right in the image, +y up. ``rotation`` is world_from_camera, so a
point p_cam in camera coordinates is ``position + rotation @ p_cam`` in the world.
Images have row 0 at the top. Depth is the metric distance along the view axis
(−z_cam), not the ray length; pixels beyond ``max_depth_m`` (sky) are NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole camera: image size [px] and vertical field of view [rad]."""

    width: int
    height: int
    fovy_rad: float

    @property
    def focal_px(self) -> float:
        """Focal length f [px] (square pixels): f = (H/2) / tan(fovy/2)."""
        return 0.5 * self.height / np.tan(0.5 * self.fovy_rad)

    @property
    def principal_point(self) -> tuple[float, float]:
        """(c_u, c_v) [px], the image centre."""
        return 0.5 * self.width, 0.5 * self.height


@dataclass
class RGBDFrame:
    """One rendered RGB-D frame with its ground-truth camera pose.

    rgb: (h, w, 3) uint8. depth: (h, w) float32 metres along the view axis, NaN
    where nothing was hit within range. position: (3,) world metres.
    rotation: (3, 3) world_from_camera. time_s: simulation time of the frame.
    """

    rgb: np.ndarray
    depth: np.ndarray
    intrinsics: CameraIntrinsics
    position: np.ndarray
    rotation: np.ndarray
    time_s: float = 0.0

    def points_camera(self) -> tuple[np.ndarray, np.ndarray]:
        """Back-project valid depth pixels: (N, 3) points in the camera frame [m]
        and (N, 3) colours in 0..1 (pinhole model, u right, v down)."""
        h, w = self.depth.shape
        f = self.intrinsics.focal_px
        cu, cv = self.intrinsics.principal_point
        v, u = np.mgrid[0:h, 0:w]
        d = self.depth
        ok = np.isfinite(d) & (d > 0)
        z = d[ok].astype(np.float64)
        x = (u[ok] + 0.5 - cu) / f * z
        y = -(v[ok] + 0.5 - cv) / f * z
        pts = np.stack([x, y, -z], axis=1)
        cols = self.rgb[ok].astype(np.float32) / 255.0
        return pts, cols

    def points_world(self) -> tuple[np.ndarray, np.ndarray]:
        """Back-projected points in the world frame [m] and their colours (0..1)."""
        pts, cols = self.points_camera()
        return pts @ np.asarray(self.rotation).T + np.asarray(self.position), cols
