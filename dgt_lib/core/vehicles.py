"""The four vehicles of the paper (Data Collection): specs with units in the names.

``jeep``, ``vw_van``, ``mercedes_van``, ``carla_cola`` (head order, docs/ARCHITECTURE.md).
Geometry is close to the real vehicles CARLA models — a Jeep Wrangler, a VW T2
van, a long Mercedes Sprinter and CARLA's "Carla Cola" delivery truck — and every
footprint fits the paper's 8.8 m × 2.8 m patch. Capabilities are ordered as in the
paper: the jeep (short, high, all-wheel drive) traverses the widest range of
terrain; carla_cola (9 t on two driven wheels) is the weakest climber; the
mercedes_van (long wheelbase, low clearance) high-centres on sharp ridges.

The drive model (used by :mod:`dgt_lib.world.simulator`): each driven wheel has a DC-motor-like
torque–speed line ``τ = τ_max·(throttle − ω/ω_max)`` clamped to ±τ_max, so a wheel
never spins past ``ω_max = max_speed_mps / wheel_radius_m``; every wheel has a
friction brake of up to ``brake_torque_nm``.

Example::

    from dgt_lib.core.vehicles import get_vehicle
    jeep = get_vehicle("jeep")
    jeep.min_turn_radius_m   # 3.5 m
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dgt_lib.core.config import VEHICLES

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


def _deg(a: float) -> float:
    return math.radians(a)


VEHICLE_SPECS: dict[str, VehicleSpec] = {
    # Jeep Wrangler (2-door): 2.46 m wheelbase, lifted, 33" tyres, AWD.
    "jeep": VehicleSpec(
        name="jeep", wheelbase_m=2.46, track_m=1.60, length_m=4.29, width_m=1.89,
        height_m=1.85, ground_clearance_m=0.38, wheel_radius_m=0.40, mass_kg=1800.0,
        drive="awd", drive_torque_nm=1200.0, brake_torque_nm=2500.0, max_speed_mps=20.0,
        max_steer_rad=_deg(35.0), camera=CameraMount(0.6, 1.35, _deg(20.0)),
        drag_area_m2=1.5, color=(0.20, 0.35, 0.20),
    ),
    # VW T2 van: 2.40 m wheelbase, low power, rear-wheel drive.
    "vw_van": VehicleSpec(
        name="vw_van", wheelbase_m=2.40, track_m=1.40, length_m=4.50, width_m=1.72,
        height_m=1.95, ground_clearance_m=0.20, wheel_radius_m=0.33, mass_kg=1500.0,
        drive="rwd", drive_torque_nm=750.0, brake_torque_nm=2000.0, max_speed_mps=20.0,
        max_steer_rad=_deg(32.0), camera=CameraMount(1.6, 1.45, _deg(20.0)),
        drag_area_m2=1.9, color=(0.85, 0.45, 0.15),
    ),
    # Mercedes Sprinter, long wheelbase: 3.9 m wheelbase, 0.14 m under the floor.
    "mercedes_van": VehicleSpec(
        name="mercedes_van", wheelbase_m=3.90, track_m=1.70, length_m=5.90, width_m=2.00,
        height_m=2.40, ground_clearance_m=0.14, wheel_radius_m=0.33, mass_kg=2800.0,
        drive="rwd", drive_torque_nm=1500.0, brake_torque_nm=3500.0, max_speed_mps=20.0,
        max_steer_rad=_deg(35.0), camera=CameraMount(2.4, 1.70, _deg(20.0)),
        drag_area_m2=2.6, color=(0.85, 0.85, 0.88),
    ),
    # CARLA's "Carla Cola" delivery truck: 9 t, rear-wheel drive, weakest climber.
    "carla_cola": VehicleSpec(
        name="carla_cola", wheelbase_m=4.00, track_m=2.00, length_m=6.40, width_m=2.40,
        height_m=3.20, ground_clearance_m=0.30, wheel_radius_m=0.50, mass_kg=9000.0,
        drive="rwd", drive_torque_nm=4500.0, brake_torque_nm=12000.0, max_speed_mps=20.0,
        max_steer_rad=_deg(35.0), camera=CameraMount(2.6, 2.20, _deg(20.0)),
        drag_area_m2=5.0, color=(0.75, 0.10, 0.10),
    ),
}
assert tuple(VEHICLE_SPECS) == VEHICLES


class UnknownVehicleError(ValueError):
    """A vehicle name that is not one of :data:`dgt_lib.core.config.VEHICLES`."""


def get_vehicle(name: str | VehicleSpec) -> VehicleSpec:
    """The :class:`VehicleSpec` called ``name`` (a spec passes through unchanged)."""
    if isinstance(name, VehicleSpec):
        return name
    try:
        return VEHICLE_SPECS[name]
    except (KeyError, TypeError):
        raise UnknownVehicleError(
            f"unknown vehicle {name!r}; valid vehicles: {', '.join(VEHICLES)}"
        ) from None


def vehicle_index(name: str) -> int:
    """Head index of a vehicle (its position in :data:`VEHICLES`)."""
    return VEHICLES.index(get_vehicle(name).name)


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
