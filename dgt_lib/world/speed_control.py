"""Longitudinal speed control: PID with feed-forward on a target speed, as the paper's
vehicles keep their commanded 5 m/s (paper: Locomotion; Controller)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from dgt_lib.core.vehicle_spec import AIR_DENSITY_KGPM3, GRAVITY_MPS2, VehicleSpec


@dataclass
class SpeedController:
    """PID speed controller with feed-forward for rolling resistance, drag and grade
    (paper, Controller Integration). Output: (throttle ∈ [−1, 1], brake ∈ [0, 1]).

    The wheel torque wanted in total is τ = r·m·a with
    a = g·(C_rr·cos φ + sin φ) + ½ρC_dA·v²/m + k_p·e + k_i·∫e + k_d·ė,
    e = v* − v, φ the pitch (uphill positive). The motors' back-EMF term is added
    back to the throttle; torque below what the motors give at zero throttle
    comes from the brakes.
    """

    vehicle: VehicleSpec
    kp: float = 1.5  # [1/s]
    ki: float = 0.6  # [1/s²]
    kd: float = 0.0  # [1]
    integral_limit: float = 4.0  # |∫e| limit [m]
    integral_band_mps: float = 1.0  # integrate only while |e| is below this [m/s]
    _integral: float = field(default=0.0, init=False)
    _last_error: float | None = field(default=None, init=False)

    def reset(self) -> None:
        """Forget the integral and derivative memory."""
        self._integral = 0.0
        self._last_error = None

    def __call__(
        self, target_mps: float, speed_mps: float, pitch_rad: float, dt_s: float
    ) -> tuple[float, float]:
        """One control update: target and measured speed along the heading [m/s],
        pitch φ [rad] (nose-up positive), period [s] → (throttle, brake)."""
        v = self.vehicle
        e = target_mps - speed_mps
        de = 0.0 if self._last_error is None else (e - self._last_error) / dt_s
        self._last_error = e
        if abs(target_mps) < 0.05 and abs(speed_mps) < 0.3:
            self._integral = 0.0
            return 0.0, 1.0  # hold still
        sign = 1.0 if target_mps >= 0 else -1.0
        resist = GRAVITY_MPS2 * v.rolling_resistance * math.cos(pitch_rad) + (
            0.5 * AIR_DENSITY_KGPM3 * v.drag_area_m2 * speed_mps**2 / v.mass_kg)
        a_ff = sign * resist + GRAVITY_MPS2 * math.sin(pitch_rad)
        integral = min(max(self._integral + e * dt_s, -self.integral_limit),
                       self.integral_limit)
        throttle, brake = self._actuate(a_ff + self.kp * e + self.ki * integral + self.kd * de,
                                        speed_mps, sign)
        saturated = (throttle >= 1.0 and e > 0) or (brake >= 1.0 and e < 0) or (
            throttle <= -1.0 and e < 0)
        if not saturated and abs(e) < self.integral_band_mps:
            # Anti-windup: integrate only near the target and while actuators have room.
            self._integral = integral
        return throttle, brake

    def _actuate(self, accel: float, speed_mps: float, sign: float) -> tuple[float, float]:
        """Wanted acceleration [m/s²] → throttle (adds the back-EMF term) or brakes."""
        v = self.vehicle
        torque = v.wheel_radius_m * v.mass_kg * accel  # total wheel torque wanted [N·m]
        n_t = v.driven_wheels * v.drive_torque_nm
        back_emf = speed_mps / v.max_speed_mps  # throttle that gives zero motor torque
        throttle = torque / n_t + back_emf
        if sign * throttle >= 0 or sign * torque >= 0:
            return min(max(float(throttle), -1.0), 1.0), 0.0
        # More braking than the motors give at zero throttle: friction brakes.
        brake = (abs(torque) - abs(back_emf) * n_t) / (4 * v.brake_torque_nm)
        return 0.0, min(max(float(brake), 0.0), 1.0)
