"""What a vehicle is: :class:`VehicleSpec`, its fields with their units in the names, and
what follows from them (turning radii, centre of mass, torque-limited climb, footprint).

The four named vehicles are files read into specs (:mod:`dgt_lib.core.vehicles`); a user's
vehicle file is read the same way (:mod:`dgt_lib.core.vehicle_file`), and the rules a spec
must keep are :mod:`dgt_lib.core.vehicle_rules`.

The drive model (used by :mod:`dgt_lib.world.simulator`): each driven wheel has a
DC-motor-like torque–speed line ``τ = τ_max·(throttle − ω/ω_max)`` clamped to ±τ_max, so a
wheel never spins past ``ω_max = max_speed_mps / wheel_radius_m``; every wheel has a
friction brake of up to ``brake_torque_nm``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

GRAVITY_MPS2 = 9.81  # [m/s²]
AIR_DENSITY_KGPM3 = 1.2  # [kg/m³]


@dataclass(frozen=True)
class CameraMount:
    """RGB-D camera pose on the chassis: ``forward_m`` ahead of and ``up_m`` above the
    chassis origin (midway between the axles, at wheel-centre height), looking
    forward and pitched down by ``pitch_down_rad``."""

    forward_m: float
    up_m: float
    pitch_down_rad: float


@dataclass(frozen=True)
class VehicleSpec:
    """One vehicle. Lengths in metres, masses in kg, torques in N·m per wheel.

    ``drive`` is ``"awd"`` (all four wheels driven) or ``"rwd"`` (rear wheels).
    ``rolling_resistance`` is the coefficient C_rr, ``drag_area_m2`` is C_d·A.
    """

    name: str
    wheelbase_m: float
    track_m: float
    length_m: float
    width_m: float
    height_m: float
    ground_clearance_m: float
    wheel_radius_m: float
    mass_kg: float
    drive: str
    drive_torque_nm: float  # per driven wheel, at stall
    brake_torque_nm: float  # per wheel
    max_speed_mps: float  # wheel-speed cap of the motors
    max_steer_rad: float  # road-wheel angle of the virtual centre wheel
    camera: CameraMount
    rolling_resistance: float = 0.015
    drag_area_m2: float = 1.5
    color: tuple[float, float, float] = (0.8, 0.8, 0.8)

    @property
    def com_height_m(self) -> float:
        """Centre of mass above the ground [m]: a quarter of the body height above its
        underside (the MuJoCo model's, ``world/mujoco_model.py``)."""
        return self.ground_clearance_m + 0.25 * (self.height_m - self.ground_clearance_m)

    @property
    def rollover_accel_mps2(self) -> float:
        """Lateral acceleration that tips the vehicle on level ground, g·(track/2)/h_cg
        [m/s²] (the static stability factor of a rigid body)."""
        return 9.81 * 0.5 * self.track_m / self.com_height_m

    @property
    def min_turn_radius_m(self) -> float:
        """R_min = L / tan(δ_max) [m] (kinematic bicycle, rear-axle centre)."""
        return self.wheelbase_m / math.tan(self.max_steer_rad)

    @property
    def centre_turn_radius_m(self) -> float:
        """Minimum turning radius of the body centre (ℓ/2 ahead of the rear axle) [m]:
        √(R_min² + (ℓ/2)²). Hybrid A* plans the body centre, so its arcs use this radius."""
        return math.hypot(self.min_turn_radius_m, 0.5 * self.wheelbase_m)

    @property
    def driven_wheels(self) -> int:
        """How many wheels the motors drive (4 for AWD, 2 for RWD)."""
        return 4 if self.drive == "awd" else 2

    @property
    def max_wheel_speed_radps(self) -> float:
        """ω_max = v_max / r [rad/s]: the motor torque reaches zero at this wheel speed."""
        return self.max_speed_mps / self.wheel_radius_m

    @property
    def max_climb_deg(self) -> float:
        """Steepest grade the motors can hold at standstill, torque-limited only
        (traction limits it further): sin φ = n·τ_max / (m·g·r) [deg]."""
        ratio = self.driven_wheels * self.drive_torque_nm / (
            self.mass_kg * GRAVITY_MPS2 * self.wheel_radius_m
        )
        return math.degrees(math.asin(min(1.0, ratio)))


def footprint_circles(length_m: float, width_m: float) -> tuple[np.ndarray, float]:
    """Circles covering a length × width rectangle centred on the pose.

    Returns (offsets (n,) [m] along the heading, radius [m]); n is the smallest
    odd integer ≥ length/width, so one circle sits on the pose itself, and each
    circle is the circumscribed circle of one of n equal slices of the rectangle.
    """
    if not (length_m > 0 and width_m > 0):
        raise ValueError(f"footprint (length_m, width_m) must be > 0, got {length_m}, {width_m}")
    n = max(1, math.ceil(length_m / width_m - 1e-9))
    n += 1 - n % 2
    half_slice = length_m / (2 * n)
    offsets = -length_m / 2 + (2 * np.arange(n) + 1) * half_slice
    return offsets, math.hypot(half_slice, width_m / 2)
