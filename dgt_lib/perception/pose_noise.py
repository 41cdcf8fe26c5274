"""Noisy localisation: frames placed in the BEV map with the pose a real robot would
estimate, not the simulator's (paper: Limitations → "RGB-D data is combined with simulator
ground-truth localization … Real-world deployment would require integrating a localization
framework, which would likely produce noisier results").

Each frame's camera pose gets an error before its points are back-projected into the map:

    p̂_i = p_i + b_i + ε_i,   ε_i ~ N(0, σ_xy² I₂)       (position, x and y) [m]
    ψ̂_i = ψ_i + η_i,         η_i ~ N(0, σ_ψ²)            (heading, about the vertical) [rad]
    b_i = b_{i−1} + δ_i,     δ_i ~ N(0, σ_d² I₂), b_0 = 0  (drift: odometry's slowly wandering bias)

so after n frames the bias's standard deviation is √n·σ_d. A heading error turns the whole
frame about the camera, as a wrong heading estimate would. The robot is driven, labelled and
evaluated in the true world: only the map is built from the estimated poses.

Example::

    noise = PoseNoise(sigma_xy_m=0.3, sigma_yaw_rad=math.radians(2.0))
    localise = noise.localiser(seed=7)
    acc.add_frame(localise(frame))      # the frame as a noisy localisation places it
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dgt_lib.core.camera import RGBDFrame

Localiser = Callable[[RGBDFrame], RGBDFrame]
"""A frame → the same frame at its estimated pose."""


@dataclass(frozen=True)
class PoseNoise:
    """The localisation error of every frame: per-frame position and heading noise and a
    drifting position bias (module docstring). All zero: the simulator's true poses."""

    sigma_xy_m: float = 0.0  # σ_xy, per-frame position error of each of x and y [m]
    sigma_yaw_rad: float = 0.0  # σ_ψ, per-frame heading error [rad]
    drift_m: float = 0.0  # σ_d, std of the bias's step per frame along x and y [m]

    def __post_init__(self) -> None:
        for name in ("sigma_xy_m", "sigma_yaw_rad", "drift_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"PoseNoise.{name} must be finite and ≥ 0, got {value}")

    @property
    def active(self) -> bool:
        """Whether any frame is moved at all."""
        return self.sigma_xy_m > 0 or self.sigma_yaw_rad > 0 or self.drift_m > 0

    def localiser(self, seed: int) -> Localiser:
        """A function that places successive frames at their noisy poses, the bias
        drifting from one call to the next; deterministic in ``seed`` and independent of
        any other random stream (a run's physics and steering do not change)."""
        rng = np.random.default_rng([seed, 0x9E57])  # its own stream: never the episode's
        bias = np.zeros(2)

        def localise(frame: RGBDFrame) -> RGBDFrame:
            nonlocal bias
            if not self.active:
                return frame
            bias = bias + rng.normal(0.0, self.drift_m, 2)
            dxy = bias + rng.normal(0.0, self.sigma_xy_m, 2)
            dyaw = rng.normal(0.0, self.sigma_yaw_rad)
            return perturbed(frame, dxy, dyaw)

        return localise


def yaw_rotation(angle_rad: float) -> np.ndarray:
    """The rotation by ``angle_rad`` about the world's vertical (z) axis, (3, 3)."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def perturbed(frame: RGBDFrame, dxy: np.ndarray, dyaw_rad: float) -> RGBDFrame:
    """``frame`` with its camera moved by ``dxy`` (x, y) [m] and turned by ``dyaw_rad``
    about the vertical through the camera."""
    position = np.asarray(frame.position, np.float64).copy()
    position[:2] += dxy
    rotation = yaw_rotation(float(dyaw_rad)) @ np.asarray(frame.rotation, np.float64)
    return dataclasses.replace(frame, position=position, rotation=rotation)


def pose_noise(config) -> PoseNoise:
    """The :class:`PoseNoise` of a profile's ``bev`` section (``BEVConfig``; degrees there)."""
    return PoseNoise(config.pose_sigma_xy_m, math.radians(config.pose_sigma_yaw_deg),
                     config.pose_drift_m)
