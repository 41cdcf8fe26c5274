"""Path tracking with MPPI (paper: Controller Integration).

The paper (Section "Controller Integration") tracks the Hybrid A* path with
Nav2's MPPI controller, converts its twist (v_x, ω_z) to a steering angle with
the kinematic bicycle relation, normalises it by the maximum steering angle,
and regulates speed with a PID whose feed-forward compensates rolling
resistance and drag. This module rebuilds those three parts in numpy (the per-sample
loops also compiled, :mod:`dgt_lib.navigation.control.mppi_compiled`, the same numbers faster):

- :class:`MPPIController` — Model Predictive Path Integral control as in Nav2:
  ``batch_size`` noisy (v, ω) sequences around the previous optimum are rolled
  out through a kinematic model that respects the minimum turning radius
  (|ω| ≤ |v| / r_min, Nav2's Ackermann model), scored by critics (path
  following, path alignment, speed, goal, occupancy, constraints), and averaged
  with softmax weights exp(−(S − S_min)/λ). Terrain cost is *not* a critic: the
  paper uses the directional costmap for planning only.
- :func:`~dgt_lib.navigation.control.bicycle.steering_from_twist` — δ = atan(ℓ ω_z / v_x),
  normalised by δ_max; settings in :mod:`dgt_lib.navigation.control.mppi_config`.
- The speed loop (PID + feed-forward for rolling resistance, drag and grade) is
  ``dgt_lib.world.speed_control.SpeedController``; it takes the v_x computed here.
- :class:`~dgt_lib.navigation.control.bicycle.KinematicBicycle` and
  :func:`~dgt_lib.navigation.control.bicycle.simulate_tracking` — a small plant with
  actuator lag and noise, to try the controller without the physics simulator.

Beyond Nav2's defaults (tuned for 0.5 m/s robots) the rollouts model what a
5 m/s car does: sampled speeds are integrated accelerations and sampled yaw
rates a random walk (smooth, turn-holding samples), and the car's speed loop
lags the command (first order, τ_v). The optimal ω sequence is smoothed with a
Savitzky–Golay filter as in Nav2.

Frames follow docs/ARCHITECTURE.md: world x east, y north, yaw counter-clockwise from +x.
A path is an ``(N, 3)`` array of (x [m], y [m], yaw [rad]). The pose handed to
the controller is the rear-axle centre, where the bicycle relation is exact
(:func:`rear_axle_pose` converts from a body origin).

A tiny demo::

    ctrl = MPPIController(MPPIConfig(), wheelbase_m=2.46, max_steer_rad=0.61, seed=0)
    ctrl.set_path(path)
    v_x, w_z = ctrl.compute((x, y, yaw), speed)
    steer = steering_from_twist(v_x, w_z, 2.46, 0.61)   # in [-1, 1]
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import distance_transform_edt
from scipy.signal import lfilter, savgol_coeffs

from dgt_lib.core.geometry import GridSpec
from dgt_lib.navigation.control.bicycle import resample_path, rollout_unicycle
from dgt_lib.navigation.control.mppi_config import MPPIConfig

BACKENDS = ("compiled", "numpy")
"""How :meth:`MPPIController.compute` evaluates its samples: ``"compiled"`` (numba,
:mod:`dgt_lib.navigation.control.mppi_compiled`) or ``"numpy"`` (the reference); the same
commands to the bit."""


class MPPIController:
    """Nav2-style MPPI path tracker for an Ackermann vehicle (see the module docstring).

    ``wheelbase_m`` ℓ and ``max_steer_rad`` δ_max define the minimum turning
    radius r_min = ℓ / tan δ_max; a larger ``min_turn_radius_m`` may be given
    (a smaller one is impossible for the steering and is refused). Call
    :meth:`set_path`, then :meth:`compute` once per ``model_dt``. After each call
    ``optimal_trajectory`` ``(T, 3)`` holds the predicted (x, y, yaw) of the
    chosen sequence (for plots and logging). ``seed`` makes runs repeatable.
    ``backend`` (:data:`BACKENDS`): ``"compiled"`` evaluates the samples with numba's
    kernels, ``"numpy"`` with the reference code below; both give the same commands to
    the bit (``tests/test_mppi_compiled.py``), the compiled one ~2.3× faster.
    """

    def __init__(
        self,
        cfg: MPPIConfig | None = None,
        *,
        wheelbase_m: float,
        max_steer_rad: float,
        min_turn_radius_m: float | None = None,
        seed: int = 0,
        backend: str = "compiled",
    ):
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        if backend == "compiled":
            from dgt_lib.navigation.control import mppi_compiled  # numba: imported when used
            self._kernels = mppi_compiled
        self.backend = backend
        self.cfg = cfg if cfg is not None else MPPIConfig()
        if wheelbase_m <= 0 or not 0 < max_steer_rad < math.pi / 2:
            raise ValueError("need wheelbase_m > 0 and 0 < max_steer_rad < π/2")
        steer_radius = wheelbase_m / math.tan(max_steer_rad)
        if min_turn_radius_m is None:
            min_turn_radius_m = steer_radius
        if min_turn_radius_m < steer_radius * (1 - 1e-6):
            raise ValueError(
                f"min_turn_radius_m {min_turn_radius_m:.3f} m is below ℓ/tan(δ_max) = "
                f"{steer_radius:.3f} m: the steering cannot turn that tightly"
            )
        self.wheelbase_m = float(wheelbase_m)
        self.max_steer_rad = float(max_steer_rad)
        self.min_turn_radius_m = float(min_turn_radius_m)
        self.seed = seed
        T, B = self.cfg.time_steps, self.cfg.batch_size
        f32 = np.float32
        self._eps_v = np.empty((T, B), f32)  # preallocated noise and controls
        self._eps_w = np.empty((T, B), f32)
        self._v = np.empty((T, B), f32)
        self._w = np.empty((T, B), f32)
        dt = self.cfg.model_dt
        self._alpha = dt / (self.cfg.speed_time_constant_s + dt)  # speed-lag filter gain
        self._path: np.ndarray | None = None
        self._occ_key: tuple[np.ndarray, GridSpec] | None = None
        self._clearance: np.ndarray | None = None  # (H + 2, W + 2) [m], off-map ring = 0
        self.reset()

    @classmethod
    def from_vehicle(cls, vehicle, cfg: MPPIConfig | None = None, seed: int = 0,
                     backend: str = "compiled"):
        """Build from an object with ``wheelbase_m``, ``max_steer_rad``, ``min_turn_radius_m``
        (e.g. ``dgt_lib.core.vehicles.VehicleSpec``)."""
        return cls(
            cfg,
            wheelbase_m=vehicle.wheelbase_m,
            max_steer_rad=vehicle.max_steer_rad,
            min_turn_radius_m=vehicle.min_turn_radius_m,
            seed=seed,
            backend=backend,
        )

    # -- state ---------------------------------------------------------------

    def reset(self) -> None:
        """Forget the warm start and the progress along the path; reseed the sampler."""
        T = self.cfg.time_steps
        self._rng = np.random.default_rng(self.seed)
        self._nominal = np.zeros((T, 2), np.float32)  # (v, ω) per step
        self._last_v: float | None = None
        half = self.cfg.smoothing_window // 2 if self.cfg.smoothing_window >= 3 else 0
        self._w_history = np.zeros(half, np.float32)
        self._savgol = (
            savgol_coeffs(2 * half + 1, 2).astype(np.float32) if half else np.ones(1, np.float32)
        )
        self._progress: int | None = None
        self.optimal_trajectory = np.zeros((T, 3))

    def set_path(self, path: np.ndarray) -> None:
        """Set the reference path, ``(N, 3)`` of (x [m], y [m], yaw [rad]); the goal is
        its last point. The warm start is kept (replanning should not jerk the car)."""
        pts, s = resample_path(path, self.cfg.path_resolution_m)
        self._path = pts
        self._s = s
        self._length = float(s[-1])
        tangent = np.gradient(pts[:, :2], axis=0)
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        self._tangent = tangent  # (M, 2) unit direction of travel along the points
        self._progress = None
        ds = s[1] - s[0]
        self._back = int(math.ceil(2.0 / ds))
        self._ahead = int(math.ceil((self.cfg.v_max * self.cfg.horizon_s + 2.0) / ds)) + 1

    @property
    def path(self) -> np.ndarray:
        """The resampled reference path, ``(M, 3)``."""
        if self._path is None:
            raise RuntimeError("no path: call set_path first")
        return self._path

    @property
    def optimal_sequence(self) -> np.ndarray:
        """The current optimal (v [m/s], ω [rad/s]) sequence, ``(T, 2)`` (a copy)."""
        return self._nominal.copy()

    def remaining_distance(self, pose) -> float:
        """Path length [m] from the projection of ``pose`` to the goal."""
        i = self._update_progress(float(pose[0]), float(pose[1]))
        return self._length - float(self._s[i])

    def _update_progress(self, x: float, y: float) -> int:
        """Index of the path point nearest (x, y), searched near the last one."""
        if self._path is None:
            raise RuntimeError("no path: call set_path first")
        if self._progress is None:
            lo, hi = 0, len(self._path)
        else:
            lo = max(0, self._progress - self._back)
            hi = min(len(self._path), self._progress + self._ahead)
        d2 = (self._path[lo:hi, 0] - x) ** 2 + (self._path[lo:hi, 1] - y) ** 2
        self._progress = lo + int(np.argmin(d2))
        return self._progress

    def _set_occupancy(self, occupancy: np.ndarray, grid: GridSpec) -> None:
        """Cache the clearance field [m] (distance to the nearest occupied cell)."""
        key = self._occ_key
        if key is not None and key[1] == grid and np.array_equal(key[0], occupancy):
            return
        occupancy = np.asarray(occupancy)
        if occupancy.shape != grid.shape:
            raise ValueError(f"occupancy shape {occupancy.shape} ≠ grid shape {grid.shape}")
        # docs/ARCHITECTURE.md: 0 free, 1 occupied, 2 unobserved (occupied). A ring of occupied
        # cells around the grid stands for everything off the map.
        free = np.zeros((grid.height + 2, grid.width + 2), bool)
        free[1:-1, 1:-1] = occupancy == 0
        self._clearance = (distance_transform_edt(free) * grid.resolution).astype(np.float32)
        self._occ_key = (occupancy.copy(), grid)
        if self.backend == "compiled":  # the critics' per-cell terms, looked up per point
            r_c = np.float32(self.cfg.collision_radius_m)
            r_i = np.float32(self.cfg.inflation_radius_m)
            self._cell_hit = (self._clearance < r_c).astype(np.float64)
            self._cell_near = np.clip((r_i - self._clearance) / (r_i - r_c), 0.0, 1.0)

    # -- the controller --------------------------------------------------------

    def compute(
        self,
        pose,
        speed: float,
        occupancy: np.ndarray | None = None,
        grid: GridSpec | None = None,
    ) -> tuple[float, float]:
        """One MPPI iteration: the twist (v_x [m/s], ω_z [rad/s]) to apply now.

        ``pose`` = (x, y, yaw) [m, m, rad] of the rear-axle centre (see
        :func:`rear_axle_pose`), ``speed`` the measured forward speed [m/s]: the
        rollouts' speed-loop lag starts from it.
        ``occupancy`` ``(H, W)`` on ``grid`` (0 free, 1 occupied, 2 unobserved;
        outside the grid counts as occupied) enables the occupancy critic.

        Per trajectory b the cost S_b sums, each averaged over the scored steps:
        path (cross-track distance to the path, in m), path angle
        (1 − cos(ψ − ψ_path)), speed (((v − v_ref)/v_target)² with
        v_ref = min(v_target, √(2·a_goal·d_remaining))), goal (distance to the
        goal once the remaining path is shorter than ``goal_radius_m``),
        collision (1 if any step has a footprint circle closer than
        ``collision_radius_m`` to an occupied cell, plus the fraction of such
        steps, so that even when every sample collides the least bad one wins),
        inflation and constraints
        (lateral acceleration over the limit, reversing). Softmax weighting::

            w_b = exp(−(S_b − min S) / λ) / Σ exp(−(S − min S) / λ),
            u*_t = Σ_b w_b · u_{b,t}

        and the sequence is shifted one step as the next call's warm start.
        """
        cfg = self.cfg
        if self._path is None:
            raise RuntimeError("no path: call set_path first")
        if (occupancy is None) != (grid is None):
            raise ValueError("occupancy and grid must be given together")
        x0, y0, yaw0 = (float(p) for p in pose)
        if not all(math.isfinite(p) for p in (x0, y0, yaw0, speed)):
            raise ValueError(f"pose and speed must be finite, got {pose}, {speed}")
        if occupancy is not None:
            self._set_occupancy(occupancy, grid)
        dt = cfg.model_dt
        i_robot = self._update_progress(x0, y0)
        if self._last_v is None:
            self._last_v = float(np.clip(speed, cfg.v_min, cfg.v_max))

        if self.backend == "compiled":
            v, w, cost = self._sampled_costs_compiled(x0, y0, yaw0, speed, i_robot, grid)
        else:
            v, w, cost = self._sampled_costs(x0, y0, yaw0, speed, i_robot, grid)

        # Softmax weighting of the sampled sequences (Nav2: temperature λ).
        cost -= cost.min()
        weights = np.exp(-cost / cfg.temperature)
        weights /= weights.sum()
        nominal = self._nominal
        nominal[:, 0] = np.einsum("tb,b->t", v, weights)
        nominal[:, 1] = np.einsum("tb,b->t", w, weights)
        if len(self._w_history):  # Nav2: Savitzky–Golay over past commands + the plan
            half = len(self._w_history)
            tail = np.full(half, nominal[-1, 1], np.float32)
            ext = np.concatenate([self._w_history, nominal[:, 1], tail])
            nominal[:, 1] = np.convolve(ext, self._savgol, mode="valid")
        bound = np.minimum(np.abs(nominal[:, 0]) / self.min_turn_radius_m, cfg.w_max)
        np.clip(nominal[:, 1], -bound, bound, out=nominal[:, 1])

        vo, wo = self._vehicle_response(nominal[:, :1], nominal[:, 1:], speed)
        xo, yo, yawo = rollout_unicycle((x0, y0, yaw0), vo, wo, dt)
        self.optimal_trajectory = np.stack([xo[:, 0], yo[:, 0], yawo[:, 0]], axis=1)
        v_cmd, w_cmd = float(nominal[0, 0]), float(nominal[0, 1])
        self._last_v = v_cmd
        if len(self._w_history):
            self._w_history[:-1] = self._w_history[1:]
            self._w_history[-1] = w_cmd
        nominal[:-1] = nominal[1:].copy()  # warm start: shift by one step
        return v_cmd, w_cmd

    def _sampled_costs(self, x0: float, y0: float, yaw0: float, speed: float, i_robot: int,
                       grid: GridSpec | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The reference (numpy): sampled commands v, ω ``(T, B)`` and each one's cost
        S ``(B,)``; the occupancy critic when ``grid`` is given."""
        v, w = self._sample()
        v_act, w_act = self._vehicle_response(v, w, speed)
        # Rollouts in a frame centred on the robot (float32 keeps its precision there).
        x, y, yaw = rollout_unicycle((0.0, 0.0, yaw0), v_act, w_act, self.cfg.model_dt)
        cost = self._path_costs(*self._path_errors(x, y, yaw, v_act, i_robot, x0, y0),
                                i_robot, x0, y0)
        if grid is not None:
            cost += self._occupancy_cost(x, y, yaw, x0, y0, grid)
        cost += self._constraint_cost(v_act, w_act)
        return v, w, cost

    def _sampled_costs_compiled(self, x0: float, y0: float, yaw0: float, speed: float,
                                i_robot: int, grid: GridSpec | None
                                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_sampled_costs` with numba's kernels (:mod:`.mppi_compiled`), the same
        float32 operations in the same order; cosines and sines stay numpy's."""
        cfg, f32 = self.cfg, np.float32
        v, w, ev, ew = self._v, self._w, *self._noise()
        v_act, w_act, yaw, mid = (np.empty_like(v) for _ in range(4))
        a = self._alpha
        self._kernels.sample_rollouts(
            ev, ew, self._nominal[:, 0], self._nominal[:, 1], f32(self._last_v),
            f32(cfg.model_dt), f32(cfg.accel_std), f32(cfg.decel_max), f32(cfg.accel_max),
            f32(cfg.v_min), f32(cfg.v_max), f32(cfg.w_rate_std * cfg.model_dt),
            f32(1.0 / self.min_turn_radius_m), f32(cfg.w_max), f32(a), f32(a - 1.0),
            f32((1.0 - a) * speed), f32(yaw0), v, w, v_act, w_act, yaw, mid)
        x, y = np.empty_like(v), np.empty_like(v)
        first, every = cfg.path_point_step - 1, cfg.path_point_step
        scored = (cfg.time_steps - first + every - 1) // every
        cross, angle_err, speed_err = (np.empty((scored, cfg.batch_size), f32)
                                       for _ in range(3))
        wx, wy, tx, ty, s_win, path_yaw = self._window(i_robot, x0, y0)
        self._kernels.project_on_path(
            v_act, np.cos(mid), np.sin(mid), yaw, f32(cfg.model_dt), first, every, wx, wy,
            tx, ty, s_win, path_yaw, f32(self._length), f32(cfg.target_speed),
            f32(2.0 * cfg.goal_decel), f32(1.0 / cfg.target_speed), x, y, cross, angle_err,
            speed_err)
        sel = slice(first, None, every)
        cost = self._path_costs(cross, angle_err, speed_err, x[sel], y[sel], i_robot, x0, y0)
        if grid is not None:
            occupancy = np.empty_like(cost)
            self._kernels.occupancy_cost(
                x, y, np.cos(yaw), np.sin(yaw),
                np.array(cfg.footprint_offsets_m, f32), self._cell_hit, self._cell_near,
                f32(x0 - grid.origin_xy[0]), f32(y0 - grid.origin_xy[1]),
                f32(1.0 / grid.resolution), f32(cfg.collision_weight),
                f32(cfg.inflation_weight), occupancy)
            cost += occupancy
        cost += self._constraint_cost(v_act, w_act)
        return v, w, cost

    def _noise(self) -> tuple[np.ndarray, np.ndarray]:
        """Standard normal noise ``(T, B)`` for speeds and yaw rates; sample 0 none."""
        ev, ew = self._eps_v, self._eps_w
        self._rng.standard_normal(out=ev, dtype=np.float32)
        self._rng.standard_normal(out=ew, dtype=np.float32)
        ev[:, 0] = 0.0
        ew[:, 0] = 0.0
        return ev, ew

    def _sample(self) -> tuple[np.ndarray, np.ndarray]:
        """Noisy (v, ω) sequences ``(T, B)`` around the warm start, made feasible.

        Speed noise is drawn on the acceleration (std ``accel_std``), clipped to
        [−decel_max, accel_max] and integrated from the last command by a
        cumulative sum, so sampled speeds are smooth ramps that can reach the
        target; then v ∈ [v_min, v_max]. Yaw-rate noise is a random walk
        (increments of std ``w_rate_std``·dt, again a cumulative sum), so a sample
        can hold a turn; ω is clipped to |ω| ≤ min(ω_max, |v| / r_min) (Nav2's
        Ackermann constraint). Sample 0 is the warm start itself.
        """
        cfg = self.cfg
        dt = np.float32(cfg.model_dt)
        v, w, ev, ew = self._v, self._w, *self._noise()
        nominal_v = self._nominal[:, 0]
        accel = np.diff(nominal_v, prepend=np.float32(self._last_v)) / dt  # (T,)
        np.multiply(ev, np.float32(cfg.accel_std), out=v)
        v += accel[:, None]
        np.clip(v, -cfg.decel_max, cfg.accel_max, out=v)
        v *= dt
        np.cumsum(v, axis=0, out=v)
        v += np.float32(self._last_v)
        np.clip(v, cfg.v_min, cfg.v_max, out=v)
        np.multiply(ew, np.float32(cfg.w_rate_std * cfg.model_dt), out=w)
        np.cumsum(w, axis=0, out=w)
        w += self._nominal[:, 1:]
        bound = np.abs(v) * np.float32(1.0 / self.min_turn_radius_m)
        np.minimum(bound, np.float32(cfg.w_max), out=bound)
        np.minimum(w, bound, out=w)
        np.negative(bound, out=bound)
        np.maximum(w, bound, out=w)
        return v, w

    def _vehicle_response(self, v, w, speed: float) -> tuple[np.ndarray, np.ndarray]:
        """Speed and yaw rate ``(T, B)`` the vehicle actually achieves for commands (v, ω).

        The speed loop is a first-order lag with time constant τ_v from the
        measured ``speed`` (backward Euler, α = dt / (τ_v + dt))::

            v̂_t = α·v_t + (1 − α)·v̂_{t−1},   v̂_{−1} = measured speed

        run over all samples at once as an IIR filter along time (``lfilter``; a
        BLAS matrix product is far slower with multithreaded BLAS on a busy
        machine). Steering fixes the curvature κ = ω / v (as
        :func:`steering_from_twist` does), so the yaw rate is ω̂ = v̂·ω / v.
        """
        a = self._alpha
        zi = np.full((1, v.shape[1]), (1.0 - a) * speed, np.float32)
        v_act = lfilter(
            np.array([a], np.float32), np.array([1.0, a - 1.0], np.float32), v, axis=0, zi=zi
        )[0]
        v_safe = np.where(v < 0, np.float32(-1.0), np.float32(1.0)) * np.maximum(
            np.abs(v), np.float32(0.05)
        )
        return v_act, w * (v_act / v_safe)

    def _window(self, i_robot: int, x0: float, y0: float) -> tuple[np.ndarray, ...]:
        """The path points the rollouts are projected on, around the robot's progress,
        float32 ``(M,)`` each: position relative to the robot (x, y) [m], unit tangent
        (x, y), arc length s [m] and yaw [rad]."""
        lo = max(0, i_robot - self._back)
        hi = min(len(self._path), i_robot + self._ahead)
        win = self._path[lo:hi]
        return ((win[:, 0] - x0).astype(np.float32), (win[:, 1] - y0).astype(np.float32),
                self._tangent[lo:hi, 0].astype(np.float32),
                self._tangent[lo:hi, 1].astype(np.float32),
                self._s[lo:hi].astype(np.float32), win[:, 2].astype(np.float32))

    def _path_errors(self, x, y, yaw, v, i_robot: int, x0: float, y0: float
                     ) -> tuple[np.ndarray, ...]:
        """Every ``path_point_step``-th rollout point ``(T', B)`` projected on the tangent
        of its nearest path point in the window: distance to the path [m], yaw error
        [rad], speed error (v − v_ref)/v_target, and the points' x, y [m]."""
        cfg = self.cfg
        wx, wy, tx, ty, s_win, path_yaw = self._window(i_robot, x0, y0)
        sel = slice(cfg.path_point_step - 1, None, cfg.path_point_step)
        px, py = x[sel], y[sel]  # (T', B)
        # argmin_j |p − w_j|² = argmin_j (|w_j|² − 2 p·w_j): one product, no BLAS
        # (einsum's own loop: multithreaded BLAS on a K = 2 product only adds overhead).
        pts = np.stack([px, py], axis=-1)  # (T', B, 2)
        score = np.einsum("tbk,kw->tbw", pts, np.stack([-2.0 * wx, -2.0 * wy]))
        score += wx * wx + wy * wy
        j = score.argmin(axis=2)
        ex, ey = px - wx[j], py - wy[j]
        lateral = ex * ty[j] - ey * tx[j]
        along = ex * tx[j] + ey * ty[j]
        s = s_win[j] + along
        # Before the start or past the goal the tangent line does not count: the
        # overshoot along it is distance from the path too.
        beyond = np.maximum(-s, 0.0) + np.maximum(s - np.float32(self._length), 0.0)
        cross = np.sqrt(lateral * lateral + beyond * beyond)  # distance to the path [m]
        remaining = np.maximum(np.float32(self._length) - s, 0.0)
        v_ref = np.minimum(np.float32(cfg.target_speed), np.sqrt(2.0 * cfg.goal_decel * remaining))
        speed_err = (v[sel] - v_ref) * np.float32(1.0 / cfg.target_speed)
        return cross, yaw[sel] - path_yaw[j], speed_err, px, py

    def _path_costs(self, cross, angle_err, speed_err, px, py, i_robot: int, x0: float,
                    y0: float) -> np.ndarray:
        """Path, path-angle, speed and goal critics ``(B,)`` from :meth:`_path_errors`."""
        cfg = self.cfg
        align = 1.0 - np.cos(angle_err)
        cost = cfg.path_weight * cross.mean(axis=0)
        cost += cfg.path_angle_weight * align.mean(axis=0)
        cost += cfg.speed_weight * (speed_err * speed_err).mean(axis=0)
        if self._length - self._s[i_robot] < cfg.goal_radius_m:
            gx, gy = self._path[-1, 0] - x0, self._path[-1, 1] - y0
            cost += cfg.goal_weight * np.hypot(px - np.float32(gx), py - np.float32(gy)).mean(0)
        return cost

    def _occupancy_cost(self, x, y, yaw, x0: float, y0: float, grid: GridSpec) -> np.ndarray:
        """Collision and inflation critics ``(B,)`` by integer lookups in the clearance
        field (distance to the nearest occupied cell centre, per footprint circle);
        points off the grid land on its zero border (occupied)."""
        cfg = self.cfg
        clear = self._clearance
        Hp, Wp = clear.shape
        inv = np.float32(1.0 / grid.resolution)
        ox = np.float32(x0 - grid.origin_xy[0])
        oy = np.float32(y0 - grid.origin_xy[1])
        r_c, r_i = np.float32(cfg.collision_radius_m), np.float32(cfg.inflation_radius_m)
        collide = np.zeros(x.shape[1], np.float32)
        inflate = np.zeros(x.shape[1], np.float32)
        for off in cfg.footprint_offsets_m:
            cx, cy = x + ox, y + oy
            if off != 0.0:
                cx += np.float32(off) * np.cos(yaw)
                cy += np.float32(off) * np.sin(yaw)
            col = np.clip(np.floor(cx * inv) + 1, 0, Wp - 1).astype(np.intp)
            row = np.clip(np.floor(cy * inv) + 1, 0, Hp - 1).astype(np.intp)
            d = clear.ravel()[row * Wp + col]  # (T, B) clearance [m]
            hit = d < r_c
            collide += hit.mean(axis=0)
            collide += hit.any(axis=0)
            inflate += np.clip((r_i - d) / (r_i - r_c), 0.0, 1.0).mean(axis=0)
        return cfg.collision_weight * collide + cfg.inflation_weight * inflate

    def _constraint_cost(self, v, w) -> np.ndarray:
        """Constraint critic ``(B,)``: lateral acceleration above the limit and reversing."""
        cfg = self.cfg
        excess = np.maximum(np.abs(v * w) - np.float32(cfg.lateral_accel_max), 0.0)
        cost = (excess * np.float32(1.0 / cfg.lateral_accel_max)).mean(axis=0)
        if cfg.v_min < 0:
            cost += np.maximum(-v, 0.0).mean(axis=0) * np.float32(1.0 / cfg.target_speed)
        return cfg.constraint_weight * cost
