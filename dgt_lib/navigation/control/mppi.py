"""Path tracking with MPPI (paper: Controller Integration).

The paper tracks the Hybrid A* path with Nav2's MPPI controller, converts its twist
(v_x, ω_z) to a steering angle with the kinematic bicycle relation and regulates speed with
a PID whose feed-forward compensates rolling resistance and drag. One MPPI iteration, as
:meth:`MPPIController.compute` runs it:

1. **sample** B noisy (v, ω) sequences of T steps around the warm start
   (:func:`~dgt_lib.navigation.control.sampling.sample_controls`; with
   ``cfg.ancillary_fraction`` > 0 that share of them around pure pursuit's rollout along the
   path instead, :mod:`~dgt_lib.navigation.control.ancillary`);
2. **roll out** each through the vehicle's speed lag and the unicycle/bicycle kinematics
   (:func:`~dgt_lib.navigation.control.sampling.vehicle_response`,
   :func:`~dgt_lib.navigation.control.bicycle.rollout_unicycle`);
3. **score** each rollout with the critics, S_b (:mod:`dgt_lib.navigation.control.critics`);
4. **weight** them, w_b = exp(−(S_b − min S)/λ)/η (:func:`mppi_weights`), and average:
   u*_t = Σ_b w_b u_{b,t} (:func:`weighted_sequence`), smoothed (Savitzky–Golay, as Nav2)
   and clipped to the turning radius;
5. **send** u*_0 and keep u*_{1…T−1} as the next call's **warm start** (:func:`shift`).

Steps 1–3 run in numpy (``backend="numpy"``, the reference, readable) or in numba's
kernels (``"compiled"``, :mod:`dgt_lib.navigation.control.mppi_compiled`, the default):
the same commands to the bit. Both draw their noise from
:class:`~dgt_lib.navigation.control.noise_compiled.NormalStream`, numpy's
``default_rng(seed)`` stream compiled. The twist becomes a steering command with
:func:`~dgt_lib.navigation.control.bicycle.steering_from_twist`; the speed loop is
``dgt_lib.world.speed_control.SpeedController``.

Frames follow docs/ARCHITECTURE.md: world x east, y north, yaw counter-clockwise from +x.
The pose handed to the controller is the rear-axle centre, where the bicycle relation is
exact (:func:`~dgt_lib.navigation.control.bicycle.rear_axle_pose`). A tiny demo::

    ctrl = MPPIController(MPPIConfig(), wheelbase_m=2.46, max_steer_rad=0.61, seed=0)
    ctrl.set_path(path)
    v_x, w_z = ctrl.compute((x, y, yaw), speed)
    steer = steering_from_twist(v_x, w_z, 2.46, 0.61)   # in [-1, 1]
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_coeffs

from dgt_lib.core.controller import MPPIConfig
from dgt_lib.core.geometry import GridSpec
from dgt_lib.navigation.control import critics
from dgt_lib.navigation.control.ancillary import ancillary_count, bias_noise, pure_pursuit_rollout
from dgt_lib.navigation.control.bicycle import rollout_unicycle
from dgt_lib.navigation.control.noise_compiled import NormalStream
from dgt_lib.navigation.control.reference_path import ReferencePath
from dgt_lib.navigation.control.sampling import (
    draw_noise,
    sample_controls,
    speed_lag_gain,
    vehicle_response,
)

BACKENDS = ("compiled", "numpy")
"""How :meth:`MPPIController.compute` evaluates its samples: ``"compiled"`` (numba,
:mod:`dgt_lib.navigation.control.mppi_compiled`) or ``"numpy"`` (the reference); the same
commands to the bit."""


# ----------------------------------------------------------------------------- weighting


def mppi_weights(cost: np.ndarray, temperature: float) -> np.ndarray:
    """The importance weights of the samples ``(B,)`` from their costs S ``(B,)``::

        w_b = exp(−(S_b − min S) / λ) / η,   η = Σ_b exp(−(S_b − min S) / λ)

    Subtracting min S keeps the exponentials in range; a small λ (``temperature``) gives
    nearly all the weight to the cheapest sample, a large one averages them all."""
    shifted = cost - cost.min()
    weights = np.exp(-shifted / temperature)
    weights /= weights.sum()
    return weights


def weighted_sequence(v: np.ndarray, w: np.ndarray, weights: np.ndarray, out: np.ndarray
                      ) -> np.ndarray:
    """u*_t = Σ_b w_b u_{b,t}: the weighted mean of the sampled (v, ω) ``(T, B)``, into
    ``out`` ``(T, 2)``."""
    out[:, 0] = np.einsum("tb,b->t", v, weights)
    out[:, 1] = np.einsum("tb,b->t", w, weights)
    return out


def smooth_yaw_rates(w_plan: np.ndarray, history: np.ndarray, coeffs: np.ndarray
                     ) -> np.ndarray:
    """Nav2's Savitzky–Golay filter over the past commands ``history`` and the planned
    ω ``(T,)`` (the last value held beyond the horizon)."""
    half = len(history)
    tail = np.full(half, w_plan[-1], np.float32)
    ext = np.concatenate([history, w_plan, tail])
    return np.convolve(ext, coeffs, mode="valid")


def shift(sequence: np.ndarray) -> None:
    """The warm start: the optimal sequence moved one step earlier, in place (its last
    step repeated)."""
    sequence[:-1] = sequence[1:].copy()


def slow_corners(sequence: np.ndarray, a_lat_max: float) -> None:
    """Slow every step of a (v [m/s], ω [rad/s]) ``(T, 2)`` sequence whose lateral
    acceleration |v·ω| exceeds ``a_lat_max`` [m/s²] to it, in place, keeping its curvature
    κ = ω/v: both scale by √(a_lat_max / |v·ω|). A roll limit: a corner is driven slower,
    never wider."""
    a_lat = np.abs(sequence[:, 0] * sequence[:, 1])
    over = a_lat > a_lat_max
    if over.any():
        scale = np.sqrt(np.float32(a_lat_max) / a_lat[over]).astype(np.float32)
        sequence[over] *= scale[:, None]


# ----------------------------------------------------------------------------- controller


@dataclass(frozen=True)
class SampledRollouts:
    """One call's samples, kept when ``MPPIController.keep_rollouts`` is set (numpy
    backend): the commands ``v`` [m/s], ``w`` [rad/s] and the rollout positions ``x``,
    ``y`` [m] in the world, all ``(T, B)``; each critic's term ``(B,)`` by name and their
    sum, the cost S ``(B,)``."""

    v: np.ndarray
    w: np.ndarray
    x: np.ndarray
    y: np.ndarray
    terms: dict[str, np.ndarray]
    cost: np.ndarray


class MPPIController:
    """Nav2-style MPPI path tracker for an Ackermann vehicle (see the module docstring).

    ``wheelbase_m`` ℓ and ``max_steer_rad`` δ_max define the minimum turning radius
    r_min = ℓ / tan δ_max; a larger ``min_turn_radius_m`` may be given (a smaller one is
    impossible for the steering and is refused). Call :meth:`set_path`, then
    :meth:`compute` once per ``model_dt``. After each call ``optimal_trajectory``
    ``(T, 3)`` holds the predicted (x, y, yaw) of the chosen sequence and ``last_costs``
    ``(B,)`` the sampled sequences' costs S (for plots). ``seed`` makes runs repeatable.
    ``backend`` (:data:`BACKENDS`) picks numba's kernels or the numpy reference.
    ``roll_accel_mps2``: the lateral acceleration that tips the vehicle [m/s²], for
    ``cfg.roll_limit_fraction`` (:func:`slow_corners`).
    ``weighting`` (default :func:`mppi_weights`) maps (S, λ) to the weights; with
    ``keep_rollouts`` the numpy backend keeps each call's :class:`SampledRollouts` in
    ``last_rollouts``.
    """

    weighting: Callable[[np.ndarray, float], np.ndarray] = staticmethod(mppi_weights)
    keep_rollouts: bool = False
    last_rollouts: SampledRollouts | None = None

    def __init__(self, cfg: MPPIConfig | None = None, *, wheelbase_m: float,
                 max_steer_rad: float, min_turn_radius_m: float | None = None, seed: int = 0,
                 backend: str = "compiled", roll_accel_mps2: float | None = None):
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
                f"{steer_radius:.3f} m: the steering cannot turn that tightly")
        self.wheelbase_m = float(wheelbase_m)
        self.max_steer_rad = float(max_steer_rad)
        self.min_turn_radius_m = float(min_turn_radius_m)
        self.roll_accel_mps2 = roll_accel_mps2
        self.seed = seed
        T, B = self.cfg.time_steps, self.cfg.batch_size
        # preallocated noise (ε_v, ε_ω) and sampled controls (v, ω), (T, B) float32 each
        self._eps_v, self._eps_w, self._v, self._w = (np.empty((T, B), np.float32)
                                                      for _ in range(4))
        self._alpha = speed_lag_gain(self.cfg)
        self._ref: ReferencePath | None = None
        self._occ_key: tuple[np.ndarray, GridSpec] | None = None
        self._clearance: np.ndarray | None = None  # (H + 2, W + 2) [m], off-map ring = 0
        self._cost_key: np.ndarray | None = None
        self._terrain: np.ndarray | None = None  # (K, H, W) C(1 + β_c C), float32
        self.reset()

    @classmethod
    def from_vehicle(cls, vehicle, cfg: MPPIConfig | None = None, seed: int = 0,
                     backend: str = "compiled"):
        """Build from an object with ``wheelbase_m``, ``max_steer_rad``, ``min_turn_radius_m``
        and optionally ``rollover_accel_mps2`` (e.g. ``dgt_lib.core.vehicle_spec.VehicleSpec``)."""
        return cls(cfg, wheelbase_m=vehicle.wheelbase_m, max_steer_rad=vehicle.max_steer_rad,
                   min_turn_radius_m=vehicle.min_turn_radius_m, seed=seed, backend=backend,
                   roll_accel_mps2=getattr(vehicle, "rollover_accel_mps2", None))

    # -- state ---------------------------------------------------------------

    def reset(self) -> None:
        """Forget the warm start and the progress along the path; reseed the sampler."""
        T = self.cfg.time_steps
        self._rng = NormalStream(self.seed)  # numpy's default_rng(seed) normals, compiled
        self._nominal = np.zeros((T, 2), np.float32)  # the warm start, (v, ω) per step
        self._last_v: float | None = None
        half = self.cfg.smoothing_window // 2 if self.cfg.smoothing_window >= 3 else 0
        self._w_history = np.zeros(half, np.float32)
        self._savgol = (savgol_coeffs(2 * half + 1, 2).astype(np.float32) if half
                        else np.ones(1, np.float32))
        if self._ref is not None:
            self._ref.progress = None
        self.optimal_trajectory = np.zeros((T, 3))
        self.last_costs: np.ndarray | None = None

    def set_path(self, path: np.ndarray) -> None:
        """Set the reference path, ``(N, 3)`` of (x [m], y [m], yaw [rad]); the goal is
        its last point. The warm start is kept (replanning should not jerk the car)."""
        cfg = self.cfg
        self._ref = ReferencePath(path, cfg.path_resolution_m, cfg.v_max * cfg.horizon_s)

    @property
    def path(self) -> np.ndarray:
        """The resampled reference path, ``(M, 3)``."""
        return self._reference().points

    @property
    def optimal_sequence(self) -> np.ndarray:
        """The warm start for the next call: the optimal (v [m/s], ω [rad/s]) sequence
        shifted one step, ``(T, 2)`` (a copy)."""
        return self._nominal.copy()

    def _reference(self) -> ReferencePath:
        if self._ref is None:
            raise RuntimeError("no path: call set_path first")
        return self._ref

    def _set_occupancy(self, occupancy: np.ndarray, grid: GridSpec) -> None:
        """Cache the clearance field [m] (and, compiled, the critics' per-cell terms)."""
        key = self._occ_key
        if key is not None and key[1] == grid and np.array_equal(key[0], occupancy):
            return
        self._clearance = critics.clearance_field(occupancy, grid)
        self._occ_key = (np.asarray(occupancy).copy(), grid)
        if self.backend == "compiled":
            self._cells = self._kernels.cell_terms(self._clearance, self.cfg)

    def _set_costmap(self, costmap: np.ndarray) -> None:
        """Cache the terrain critic's per-cell term (:func:`~dgt_lib.navigation.control.
        critics.terrain_table`)."""
        if self._cost_key is not None and np.array_equal(self._cost_key, costmap):
            return
        self._terrain = critics.terrain_table(costmap, self.cfg)
        self._cost_key = np.asarray(costmap).copy()

    def _terrain_on(self, costmap: np.ndarray | None) -> bool:
        """Whether this call runs the terrain critic: a costmap given, a weight above 0."""
        return costmap is not None and self.cfg.terrain_weight > 0

    def _noise(self, pose: tuple[float, float, float], i_robot: int
               ) -> tuple[np.ndarray, np.ndarray]:
        """Standard normal noise ``(T, B)`` for speeds and yaw rates; sample 0 none; the
        last ``ancillary_fraction`` of the samples shifted to pure pursuit's rollout from
        ``pose`` at progress ``i_robot`` (:mod:`~dgt_lib.navigation.control.ancillary`)."""
        ev, ew = draw_noise(self._rng, self._eps_v, self._eps_w)
        count = ancillary_count(self.cfg)
        if count:
            ancillary = pure_pursuit_rollout(self._ref, i_robot, pose, self._last_v, self.cfg,
                                             self.min_turn_radius_m)
            bias_noise(ev, ew, self._nominal, self._last_v, ancillary, self.cfg, count)
        return ev, ew

    # -- the controller --------------------------------------------------------

    def compute(self, pose, speed: float, occupancy: np.ndarray | None = None,
                grid: GridSpec | None = None, costmap: np.ndarray | None = None
                ) -> tuple[float, float]:
        """One MPPI iteration: the twist (v_x [m/s], ω_z [rad/s]) to apply now.

        ``pose`` = (x, y, yaw) [m, m, rad] of the rear-axle centre, ``speed`` the measured
        forward speed [m/s] (the rollouts' speed lag starts from it). ``occupancy``
        ``(H, W)`` on ``grid`` (0 free, 1 occupied, 2 unobserved; outside the grid counts
        as occupied) enables the occupancy critic; a directional ``costmap`` ``(K, H, W)``
        on the same grid, the terrain critic when ``cfg.terrain_weight`` > 0. Steps 1–5
        of the module docstring; the lines marked *ours* are options the paper's MPPI
        (``experiments.controller=paper``) leaves off.
        """
        cfg = self.cfg
        x0, y0, yaw0 = self._checked_pose(pose, speed, occupancy, grid, costmap)
        terrain = self._set_maps(occupancy, grid, costmap)
        i_robot = self._reference().update_progress(x0, y0)
        if self._last_v is None:
            self._last_v = float(np.clip(speed, cfg.v_min, cfg.v_max))
        # 1–3. sample B sequences around the warm start, roll them out, score them: S_b
        sampled_costs = (self._sampled_costs_compiled if self.backend == "compiled"
                         else self._sampled_costs)
        v, w, cost = sampled_costs(x0, y0, yaw0, speed, i_robot, grid, terrain)
        self.last_costs = cost
        # 4. weight them, w_b = exp(−(S_b − min S)/λ)/η, and average: u*_t = Σ_b w_b u_b,t
        nominal = weighted_sequence(v, w, self.weighting(cost, cfg.temperature), self._nominal)
        self._smooth_and_bound(nominal)
        if self.roll_accel_mps2 is not None and cfg.roll_limit_fraction > 0:  # ours
            slow_corners(nominal, cfg.roll_limit_fraction * self.roll_accel_mps2)
        self.optimal_trajectory = self._predicted(nominal, (x0, y0, yaw0), speed)
        # 5. send u*_0, keep u*_1…T−1 as the next call's warm start
        return self._send(nominal)

    def _checked_pose(self, pose, speed: float, occupancy, grid, costmap
                      ) -> tuple[float, float, float]:
        """(x, y, yaw) of ``pose`` as floats; ValueError for inputs that do not fit."""
        if (occupancy is None) != (grid is None):
            raise ValueError("occupancy and grid must be given together")
        if costmap is not None and (grid is None or np.shape(costmap)[1:] != grid.shape):
            raise ValueError("a costmap needs the occupancy's grid and its (H, W)")
        x0, y0, yaw0 = (float(p) for p in pose)
        if not all(math.isfinite(p) for p in (x0, y0, yaw0, speed)):
            raise ValueError(f"pose and speed must be finite, got {pose}, {speed}")
        return x0, y0, yaw0

    def _set_maps(self, occupancy, grid, costmap) -> bool:
        """Cache the occupancy's and the costmap's per-cell fields; whether the terrain
        critic runs this call."""
        if occupancy is not None:
            self._set_occupancy(occupancy, grid)
        terrain = self._terrain_on(costmap)
        if terrain:
            self._set_costmap(costmap)
        return terrain

    def _smooth_and_bound(self, nominal: np.ndarray) -> None:
        """Nav2's Savitzky–Golay smoothing of ω over the past commands, then |ω| clipped to
        what the speed allows at the minimum turning radius (and ``w_max``), in place."""
        if len(self._w_history):
            nominal[:, 1] = smooth_yaw_rates(nominal[:, 1], self._w_history, self._savgol)
        bound = np.minimum(np.abs(nominal[:, 0]) / self.min_turn_radius_m, self.cfg.w_max)
        np.clip(nominal[:, 1], -bound, bound, out=nominal[:, 1])

    def _predicted(self, nominal: np.ndarray, pose: tuple[float, float, float],
                   speed: float) -> np.ndarray:
        """The (x, y, yaw) ``(T, 3)`` the vehicle is predicted to drive with ``nominal``."""
        vo, wo = vehicle_response(nominal[:, :1], nominal[:, 1:], speed, self._alpha,
                                  self.cfg.breakaway_speed_mps)
        xo, yo, yawo = rollout_unicycle(pose, vo, wo, self.cfg.model_dt)
        return np.stack([xo[:, 0], yo[:, 0], yawo[:, 0]], axis=1)

    def _send(self, nominal: np.ndarray) -> tuple[float, float]:
        """The first command of ``nominal``; it joins the smoothing's history and the rest
        of the sequence, shifted, becomes the warm start."""
        v_cmd, w_cmd = float(nominal[0, 0]), float(nominal[0, 1])
        self._last_v = v_cmd
        if len(self._w_history):
            self._w_history[:-1] = self._w_history[1:]
            self._w_history[-1] = w_cmd
        shift(nominal)
        return v_cmd, w_cmd

    def _goal_xy(self, i_robot: int, x0: float, y0: float) -> tuple[float, float] | None:
        """The goal relative to the robot once the remaining path is within
        ``goal_radius_m`` (the goal critic is on), else None."""
        ref = self._ref
        if ref.remaining_m(i_robot) < self.cfg.goal_radius_m:
            return ref.goal_relative(x0, y0)
        return None

    def _sampled_costs(self, x0: float, y0: float, yaw0: float, speed: float, i_robot: int,
                       grid: GridSpec | None, terrain: bool = False
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Steps 1–3 in numpy (the reference): sampled commands v, ω ``(T, B)`` and each
        one's cost S ``(B,)``; the occupancy critic when ``grid`` is given, the terrain
        critic with ``terrain``."""
        cfg = self.cfg
        ev, ew = self._noise((x0, y0, yaw0), i_robot)
        v, w = sample_controls(ev, ew, self._nominal, self._last_v, cfg,
                               self.min_turn_radius_m, self._v, self._w)
        v_act, w_act = vehicle_response(v, w, speed, self._alpha, cfg.breakaway_speed_mps)
        # Rollouts in a frame centred on the robot (float32 keeps its precision there).
        x, y, yaw = rollout_unicycle((0.0, 0.0, yaw0), v_act, w_act, cfg.model_dt)
        errors = critics.path_errors(x, y, yaw, v_act, self._ref.window(i_robot, x0, y0),
                                     self._ref.length_m, cfg)
        terms = critics.path_terms(*errors, self._goal_xy(i_robot, x0, y0), cfg)
        if grid is not None:
            terms["occupancy"] = critics.occupancy_critic(
                x, y, yaw, self._clearance, (x0 - grid.origin_xy[0], y0 - grid.origin_xy[1]),
                grid.resolution, cfg)
        if terrain:
            terms["terrain"] = critics.terrain_critic(
                x, y, yaw, self._terrain, (x0 - grid.origin_xy[0], y0 - grid.origin_xy[1]),
                grid.resolution, 0.5 * self.wheelbase_m, cfg)
        terms["constraint"] = critics.constraint_critic(v_act, w_act, cfg)
        cost = critics.total_cost(terms)
        if self.keep_rollouts:
            self.last_rollouts = SampledRollouts(v.copy(), w.copy(), x + np.float32(x0),
                                                 y + np.float32(y0), terms, cost)
        return v, w, cost

    def _sampled_costs_compiled(self, x0: float, y0: float, yaw0: float, speed: float,
                                i_robot: int, grid: GridSpec | None, terrain: bool = False
                                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_sampled_costs` with numba's kernels, the same float32 operations in the
        same order (:func:`~dgt_lib.navigation.control.mppi_compiled.sampled_costs`)."""
        ev, ew = self._noise((x0, y0, yaw0), i_robot)
        return self._kernels.sampled_costs(
            ev, ew, self._nominal, self._last_v, speed, (x0, y0, yaw0),
            self._ref.window(i_robot, x0, y0), self._ref.length_m,
            self._goal_xy(i_robot, x0, y0), self.cfg, self.min_turn_radius_m, self._alpha,
            None if grid is None else (self._cells, grid), self._v, self._w,
            (self._terrain, 0.5 * self.wheelbase_m) if terrain else None)


def warm_start_trace(ctrl: MPPIController, pose, speed: float, calls: int, occupancy=None,
                     grid=None) -> dict[str, np.ndarray]:
    """MPPI called ``calls`` times from the same ``pose`` and measured ``speed`` [m/s]: a
    vehicle that does not move at the commands it gets (a heavy truck below its breakaway
    speed). Per call ``(calls,)`` [m/s]: the warm start's first two speeds
    (``warm_v0``, ``warm_v1``), the command sent (``command``, the weighted first step),
    the weighted second step (``plan_v1``, the next call's warm start ``warm_v0``) and the
    plan's mean speed over the horizon (``plan_mean``). A plan that speeds up while
    ``plan_v1`` stays at ``warm_v1`` or below is a ramp planned every call and never sent."""
    rows = []
    for _ in range(calls):
        warm = ctrl.optimal_sequence
        v_cmd, _ = ctrl.compute(pose, speed, occupancy, grid)
        plan = ctrl.optimal_sequence  # shifted: plan[0] is the weighted second step
        rows.append((warm[0, 0], warm[1, 0], v_cmd, plan[0, 0],
                     float(np.r_[v_cmd, plan[:-1, 0]].mean())))
    cols = np.asarray(rows, float).T
    return dict(zip(("warm_v0", "warm_v1", "command", "plan_v1", "plan_mean"), cols,
                    strict=True))
