"""Driving a vehicle in MuJoCo until the drive ends: the one drive loop of the kit
(paper: Experimental Protocol; closed-loop control with MPPI).

:func:`drive_loop` steps a :class:`~dgt_lib.world.simulator.Simulator` with a policy
``state -> (speed command [m/s], steer ∈ [−1, 1])`` until an
:class:`~dgt_lib.navigation.outcome.OutcomeRule` decides. On it:

- :func:`drive` — a closed-loop trial: track a planned path with MPPI at 20 Hz
  (:data:`MPPI_DT_S`), success within 5 m of the goal (the paper's rule);
- :func:`follow_path` / :func:`drive_straight` — scripted drives (pure pursuit, or a
  fixed command) that record every control step, for the physical premises.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.navigation.control.bicycle import rear_axle_pose, steering_from_twist
from dgt_lib.navigation.control.mppi import MPPIController
from dgt_lib.navigation.control.mppi_config import MPPIConfig, vehicle_footprint
from dgt_lib.navigation.control.pure_pursuit import PurePursuit
from dgt_lib.navigation.outcome import OutcomeRule, TrialOutcome
from dgt_lib.world.simulator import CONTROL_DT_S, Simulator, VehicleState
from dgt_lib.world.worlds import World

MPPI_DT_S = 0.05
"""Control period of closed-loop trials [s]: MPPI at 20 Hz (Nav2's model_dt)."""
LOG_DT_S = 0.25
"""Trajectory samples kept per trial [s]."""

Policy = Callable[[VehicleState], tuple[float, float]]
"""state → (speed command [m/s], normalised steer ∈ [−1, 1])."""


def drive_loop(sim: Simulator, policy: Policy, rule: OutcomeRule, *, goal=None,
               dt_s: float = CONTROL_DT_S,
               on_state: Callable[[VehicleState], None] | None = None) -> TrialOutcome:
    """Step ``sim`` from its current state, ``dt_s`` [s] per command of ``policy``, until
    ``rule`` decides (judged on every state, the first one included); ``on_state`` sees
    every state before it is judged. Returns the outcome; the simulator holds the last
    state."""
    goal = None if goal is None else np.asarray(goal, float)[:2]
    state = sim.state
    while True:
        if on_state is not None:
            on_state(state)
        outcome = rule.judge(state.time_s, state.position, goal, state.immobilized_s,
                             state.done_reason)
        if outcome is not None:
            return outcome
        speed, steer = policy(state)
        state = sim.step(speed_cmd_mps=float(speed), steer=float(steer), duration_s=dt_s)


def drive(world: World, vehicle: str, path: np.ndarray, goal, *, occupancy=None, grid=None,
          time_limit_s: float, mppi_batch_size: int = 1000, seed: int = 0,
          on_command: Callable[[VehicleState, float, float], None] | None = None,
          mppi_settings: Mapping[str, object] | None = None
          ) -> tuple[TrialOutcome, np.ndarray, np.ndarray]:
    """Track ``path`` (N, 3) in MuJoCo with MPPI at 20 Hz from its first pose.

    Returns (outcome, trajectory (T, 4) [t, x, y, z] every :data:`LOG_DT_S`, speed (T,)).
    Judged by :class:`OutcomeRule` with the paper's 5 m and 10 s and ``time_limit_s``.
    A path of one pose (the planner's answer when the start is already within its goal
    tolerance) has nothing to track: the vehicle holds still and the rule judges where
    it stands (success at t = 0 when that is within 5 m of the goal).
    ``on_command(state, speed_cmd [m/s], steer ∈ [−1, 1] of the steering lock)`` sees every
    command MPPI gives, with the state it answered (``benchmarks/replay_trial.py`` prints
    them). ``mppi_settings``: :class:`MPPIConfig` fields to change for this drive, e.g.
    ``{"lateral_accel_max": 2.0}`` (``benchmarks/controller_variants.py``); the experiments
    use the defaults.
    """
    spec = get_vehicle(vehicle)
    sim = Simulator(world, spec)
    path = np.asarray(path, float)
    try:
        x, y, yaw = (float(v) for v in path[0])
        sim.reset(x, y, yaw)
        if _has_length(path):
            cfg = replace(MPPIConfig(batch_size=mppi_batch_size), **vehicle_footprint(spec),
                          **(mppi_settings or {}))
            ctrl = MPPIController.from_vehicle(spec, cfg, seed=seed)
            # the controller works on the rear-axle centre, the planner on the body centre
            ctrl.set_path(rear_axle_pose(path[:, :2], path[:, 2], spec.wheelbase_m))

            def policy(state: VehicleState) -> tuple[float, float]:
                pose = rear_axle_pose(state.position, state.yaw, spec.wheelbase_m)
                v_x, w_z = ctrl.compute(pose, state.speed_mps, occupancy, grid)
                steer = steering_from_twist(v_x, w_z, spec.wheelbase_m, spec.max_steer_rad)
                if on_command is not None:
                    on_command(state, v_x, steer)
                return v_x, steer
        else:
            def policy(state: VehicleState) -> tuple[float, float]:
                return 0.0, 0.0  # hold still: nothing to track

        rows, speeds = [], []
        next_log = [0.0]

        def log(state: VehicleState) -> None:
            if state.time_s >= next_log[0]:
                rows.append((state.time_s, *state.position))
                speeds.append(state.speed_mps)
                next_log[0] += LOG_DT_S

        outcome = drive_loop(sim, policy, OutcomeRule(time_limit_s=time_limit_s), goal=goal,
                             dt_s=MPPI_DT_S, on_state=log)
        state = sim.state
        rows.append((state.time_s, *state.position))
        speeds.append(state.speed_mps)
        return outcome, np.asarray(rows, float), np.asarray(speeds, float)
    finally:
        sim.close()


def _has_length(path: np.ndarray) -> bool:
    """Whether an (N, 3) path has two distinct positions (something to track)."""
    return bool(len(path) > 1 and np.any(np.hypot(*np.diff(path[:, :2], axis=0).T) > 1e-9))


@dataclass
class Trajectory:
    """A recorded run: time (N,) [s], position (N, 3) [m], yaw (N,) [rad], speed (N,)
    [m/s], pitch (N,) [rad], chassis_contact (N,) bool, and why it ended:
    ``"goal"``, ``"timeout"``, ``"immobilized"`` or a simulator ``done_reason``."""

    time_s: np.ndarray
    position: np.ndarray
    yaw: np.ndarray
    speed_mps: np.ndarray
    pitch: np.ndarray
    chassis_contact: np.ndarray
    end_reason: str

    @property
    def distance_m(self) -> np.ndarray:
        """(N,) cumulative horizontal distance travelled [m]."""
        step = np.linalg.norm(np.diff(self.position[:, :2], axis=0), axis=1)
        return np.concatenate([[0.0], np.cumsum(step)])

    @property
    def progress_m(self) -> np.ndarray:
        """(N,) signed distance driven along the heading [m] (∫ speed dt): it
        decreases while the vehicle rolls backwards."""
        step = 0.5 * (self.speed_mps[1:] + self.speed_mps[:-1]) * np.diff(self.time_s)
        return np.concatenate([[0.0], np.cumsum(step)])


def _record(sim: Simulator, policy: Policy, rule: OutcomeRule, goal=None) -> Trajectory:
    """Run :func:`drive_loop` at the control rate and keep every state."""
    states: list[VehicleState] = []
    outcome = drive_loop(sim, policy, rule, goal=goal, on_state=states.append)
    if outcome.success:
        reason = "goal"
    elif outcome.reason in ("flipped", "diverged"):
        reason = outcome.detail  # the simulator's done_reason: flipped, off_map, diverged
    else:
        reason = outcome.reason
    return Trajectory(
        time_s=np.array([r.time_s for r in states]),
        position=np.array([r.position for r in states]),
        yaw=np.array([r.yaw for r in states]), speed_mps=np.array([r.speed_mps for r in states]),
        pitch=np.array([r.pitch for r in states]),
        chassis_contact=np.array([r.chassis_contact for r in states]), end_reason=reason)


def follow_path(
    sim: Simulator,
    path_xy: np.ndarray,
    *,
    speed_mps: float = 5.0,
    start_yaw: float | None = None,
    max_time_s: float = 120.0,
    goal_tolerance_m: float = 3.0,
    immobilized_limit_s: float = 10.0,
    reset: bool = True,
) -> Trajectory:
    """Drive along a (M, 2) waypoint path at ``speed_mps`` with pure pursuit and the
    PID speed controller at 25 Hz, from its first point (``reset=True``, heading
    along the path unless ``start_yaw``) until within ``goal_tolerance_m`` of its
    last point, immobilized for ``immobilized_limit_s`` (paper: 10 s), a simulator
    ``done_reason``, or ``max_time_s``. ``end_reason`` is ``"goal"``, ``"timeout"``,
    ``"immobilized"`` or the simulator's ``done_reason``."""
    path = np.asarray(path_xy, np.float64)
    if reset:
        d0 = path[1] - path[0]
        yaw = math.atan2(d0[1], d0[0]) if start_yaw is None else start_yaw
        sim.reset(path[0, 0], path[0, 1], yaw)
    steer = PurePursuit(path, sim.vehicle)
    rule = OutcomeRule(goal_tolerance_m, immobilized_limit_s, max_time_s)
    return _record(sim, lambda st: (speed_mps, steer(st)), rule, goal=path[-1])


def drive_straight(sim: Simulator, x: float, y: float, yaw: float, *, speed_mps: float = 5.0,
                   steer: float = 0.0, duration_s: float = 10.0) -> Trajectory:
    """Reset at (x, y, yaw) and drive ``duration_s`` at a fixed speed command and steer."""
    sim.reset(x, y, yaw)
    return _record(sim, lambda st: (speed_mps, steer),
                   OutcomeRule(immobilized_limit_s=math.inf, time_limit_s=duration_s))
