"""The kinematic bicycle: MPPI's twist → steering, the rear-axle reference point, and
a kinematic simulation for testing the tracker without physics (paper: Controller)."""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from dgt_lib.core.geometry import GridSpec


class Tracker(Protocol):
    """What :func:`simulate_tracking` drives: a path tracker called once per
    ``cfg.model_dt`` [s] with the rear-axle pose and speed, answering a twist (v_x [m/s],
    ω_z [rad/s]) — e.g. :class:`dgt_lib.navigation.control.mppi.MPPIController`."""

    cfg: object

    def set_path(self, path: np.ndarray) -> None: ...

    def compute(self, pose, speed: float, occupancy=None, grid=None, costmap=None
                ) -> tuple[float, float]: ...


def steering_from_twist(v_x, w_z, wheelbase_m: float, max_steer_rad: float, v_eps: float = 0.05):
    """Normalised steering command in [−1, 1] from a twist (paper, Controller Integration).

    Kinematic bicycle relation::

        δ = atan(ℓ · ω_z / v_x),      steer = clip(δ / δ_max, −1, 1)

    with ℓ the wheelbase [m], v_x [m/s], ω_z [rad/s]. Near standstill the
    relation is singular; ``|v_x|`` is floored at ``v_eps`` [m/s] (keeping the
    sign of v_x, zero counting as forward), so a zero twist gives zero steering
    and a yaw rate requested at rest saturates smoothly instead of dividing by
    zero. Works on scalars and arrays alike.
    """
    if wheelbase_m <= 0 or not 0 < max_steer_rad < math.pi / 2:
        raise ValueError(
            f"need wheelbase_m > 0 and 0 < max_steer_rad < π/2, got {wheelbase_m}, {max_steer_rad}"
        )
    v = np.asarray(v_x, dtype=np.float64)
    v_safe = np.where(v < 0.0, -1.0, 1.0) * np.maximum(np.abs(v), v_eps)
    delta = np.arctan(wheelbase_m * np.asarray(w_z, dtype=np.float64) / v_safe)
    steer = np.clip(delta / max_steer_rad, -1.0, 1.0)
    return float(steer) if steer.ndim == 0 else steer


class KinematicBicycle:
    """Kinematic bicycle (rear-axle reference) with actuator lag and steering noise::

        ẋ = v cos ψ,  ẏ = v sin ψ,  ψ̇ = v tan δ / ℓ,
        δ̇ = (δ_cmd + n − δ) / τ_δ,   n ~ N(0, σ_δ²) per step,
        v̇ = clip((v_cmd − v) / τ_v, −a_brake, a_max)

    The speed lag stands in for a speed loop such as
    ``dgt_lib.world.speed_control.SpeedController``.
    Semi-implicit Euler steps of ``dt`` [s]; ``seed`` drives the steering noise.
    """

    def __init__(
        self,
        wheelbase_m: float,
        max_steer_rad: float,
        *,
        steer_time_constant_s: float = 0.15,
        speed_time_constant_s: float = 0.5,
        max_accel_mps2: float = 3.0,
        max_brake_mps2: float = 6.0,
        steer_noise_std_rad: float = 0.0,
        pose=(0.0, 0.0, 0.0),
        speed: float = 0.0,
        seed: int = 0,
    ):
        if wheelbase_m <= 0 or not 0 < max_steer_rad < math.pi / 2:
            raise ValueError("need wheelbase_m > 0 and 0 < max_steer_rad < π/2")
        self.wheelbase_m = float(wheelbase_m)
        self.max_steer_rad = float(max_steer_rad)
        self.steer_tau = max(float(steer_time_constant_s), 0.0)
        self.speed_tau = max(float(speed_time_constant_s), 0.0)
        self.max_accel = float(max_accel_mps2)
        self.max_brake = float(max_brake_mps2)
        self.steer_noise = float(steer_noise_std_rad)
        self._rng = np.random.default_rng(seed)
        self.x, self.y, self.yaw = (float(p) for p in pose)
        self.speed = float(speed)
        self.steer_rad = 0.0

    @property
    def pose(self) -> tuple[float, float, float]:
        """(x [m], y [m], yaw [rad])."""
        return self.x, self.y, self.yaw

    def step(self, steer: float, speed_cmd: float, dt: float) -> None:
        """Advance ``dt`` [s] with normalised steering ``steer`` in [−1, 1] and speed
        command ``speed_cmd`` [m/s]."""
        cmd = float(np.clip(steer, -1.0, 1.0)) * self.max_steer_rad
        if self.steer_noise > 0:
            cmd += self._rng.normal(0.0, self.steer_noise)
        cmd = min(max(cmd, -self.max_steer_rad), self.max_steer_rad)
        self.steer_rad += (cmd - self.steer_rad) * min(1.0, dt / max(self.steer_tau, 1e-9))
        accel = (speed_cmd - self.speed) / max(self.speed_tau, dt)
        self.speed += min(max(accel, -self.max_brake), self.max_accel) * dt
        self.yaw += self.speed * math.tan(self.steer_rad) / self.wheelbase_m * dt
        self.x += self.speed * math.cos(self.yaw) * dt
        self.y += self.speed * math.sin(self.yaw) * dt


def simulate_tracking(
    controller: Tracker,
    plant: KinematicBicycle,
    path: np.ndarray,
    duration_s: float,
    substeps: int = 5,
    occupancy: np.ndarray | None = None,
    grid: GridSpec | None = None,
    stop_distance_m: float = 0.5,
    costmap: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Closed loop on the kinematic plant: MPPI at 1/model_dt, steering by
    :func:`steering_from_twist`, ``substeps`` plant steps per control step (``costmap``
    (K, H, W) on ``grid``: for the terrain critic).
    Stops after ``duration_s`` [s] or once the goal is within ``stop_distance_m``
    [m] and the car is nearly still.

    Returns traces, one row per control step: ``t`` (T,) [s], ``pose`` (T, 3),
    ``speed`` (T,), ``v_cmd`` (T,), ``w_cmd`` (T,), ``steer`` (T,) in [−1, 1].
    """
    controller.set_path(path)
    dt = controller.cfg.model_dt
    goal = np.asarray(path, dtype=np.float64)[-1, :2]
    rows: list[tuple[float, ...]] = []
    for k in range(int(round(duration_s / dt))):
        pose, speed = plant.pose, plant.speed
        v_cmd, w_cmd = (controller.compute(pose, speed, occupancy, grid) if costmap is None
                        else controller.compute(pose, speed, occupancy, grid, costmap))
        steer = steering_from_twist(v_cmd, w_cmd, plant.wheelbase_m, plant.max_steer_rad)
        rows.append((k * dt, *pose, speed, v_cmd, w_cmd, steer))
        if math.hypot(pose[0] - goal[0], pose[1] - goal[1]) < stop_distance_m and speed < 0.2:
            break
        for _ in range(substeps):
            plant.step(steer, v_cmd, dt / substeps)
    a = np.asarray(rows, dtype=np.float64)
    return {
        "t": a[:, 0],
        "pose": a[:, 1:4],
        "speed": a[:, 4],
        "v_cmd": a[:, 5],
        "w_cmd": a[:, 6],
        "steer": a[:, 7],
    }


def rear_axle_pose(position, yaw, wheelbase_m: float, offset_m: float | None = None):
    """(x, y, yaw) of the rear-axle centre, the reference point of the bicycle relation,
    from a body origin ``offset_m`` [m] ahead of it along the heading (default ℓ/2:
    the body centre midway between the axles, as in ``dgt_lib.world.simulator`` and
    ``dgt_lib.navigation.planner``). Scalars give a tuple; ``position`` (N, ≥2) with ``yaw``
    (N,) gives an (N, 3) array, e.g. a planner path moved to the rear axle::

        rear_path = rear_axle_pose(result.path[:, :2], result.path[:, 2], spec.wheelbase_m)
    """
    off = 0.5 * wheelbase_m if offset_m is None else offset_m
    p = np.asarray(position, dtype=np.float64)
    th = np.asarray(yaw, dtype=np.float64)
    x = p[..., 0] - off * np.cos(th)
    y = p[..., 1] - off * np.sin(th)
    if p.ndim == 1:
        return float(x), float(y), float(th)
    return np.stack([x, y, np.broadcast_to(th, x.shape)], axis=-1)


def cross_track_errors(path: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Distance [m] from each of ``positions`` ``(T, ≥2)`` to the polyline ``path``
    ``(N, ≥2)`` (exact point-to-segment projection, processed in chunks)."""
    p = np.asarray(path, dtype=np.float64)[:, :2]
    q = np.asarray(positions, dtype=np.float64)[:, :2]
    if len(p) < 2:
        raise ValueError("path needs at least two points")
    a, d = p[:-1], np.diff(p, axis=0)
    dd = np.maximum((d * d).sum(axis=1), 1e-12)
    out = np.empty(len(q))
    for i in range(0, len(q), 256):
        qc = q[i : i + 256, None, :]
        t = np.clip(((qc - a) * d).sum(axis=2) / dd, 0.0, 1.0)
        diff = qc - (a + t[..., None] * d)
        out[i : i + 256] = np.sqrt((diff * diff).sum(axis=2)).min(axis=1)
    return out


def rollout_unicycle(pose, v: np.ndarray, w: np.ndarray, dt: float):
    """Integrate speed and yaw-rate sequences from ``pose`` with cumulative sums.

    ``v``, ``w``: ``(T, B)`` [m/s], [rad/s], step t held for ``dt`` [s]. Returns
    ``x, y, yaw`` of shape ``(T, B)``: the state at the end of each step. Yaw is
    integrated exactly (ψ_t = ψ_0 + Σ ω dt); positions use the step's midpoint
    heading, which makes constant-(v, ω) arcs second-order accurate.
    """
    x0, y0, yaw0 = (float(p) for p in pose)
    dyaw = w * dt
    yaw = np.cumsum(dyaw, axis=0)
    yaw += yaw0
    mid = yaw - 0.5 * dyaw
    step = v * dt
    x = np.cumsum(step * np.cos(mid), axis=0)
    y = np.cumsum(step * np.sin(mid), axis=0)
    x += x0
    y += y0
    return x, y, yaw


def resample_path(path: np.ndarray, spacing_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Resample an ``(N, 3)`` path of (x, y, yaw) to uniform arc-length spacing.

    Returns ``(points (M, 3), s (M,))`` with s the arc length [m] of each point;
    yaw is interpolated on the circle. Consecutive duplicate points are dropped.
    Raises ``ValueError`` for fewer than two distinct points.
    """
    path = np.asarray(path, dtype=np.float64)
    if path.ndim != 2 or path.shape[1] != 3 or not np.isfinite(path).all():
        raise ValueError(f"path must be a finite (N, 3) array of (x, y, yaw), got {path.shape}")
    seg = np.hypot(np.diff(path[:, 0]), np.diff(path[:, 1]))
    keep = np.concatenate([[True], seg > 1e-9])
    path = path[keep]
    if len(path) < 2:
        raise ValueError("path needs at least two distinct points")
    s_in = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(path[:, 0]), np.diff(path[:, 1])))])
    n = max(2, int(math.ceil(s_in[-1] / spacing_m)) + 1)
    s = np.linspace(0.0, s_in[-1], n)
    x = np.interp(s, s_in, path[:, 0])
    y = np.interp(s, s_in, path[:, 1])
    c = np.interp(s, s_in, np.cos(path[:, 2]))
    sn = np.interp(s, s_in, np.sin(path[:, 2]))
    return np.stack([x, y, np.arctan2(sn, c)], axis=1), s
