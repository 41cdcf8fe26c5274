"""Driving a vehicle in MuJoCo until the drive ends: the one drive loop of the kit
(paper: Experimental Protocol; closed-loop control with MPPI).

:func:`drive_steps` steps a :class:`~dgt_lib.world.simulator.Simulator` with a policy
``state -> (speed command [m/s], steer ∈ [−1, 1])`` until an
:class:`~dgt_lib.navigation.outcome.OutcomeRule` decides, one :class:`DriveStep` at a time
(:func:`drive_loop` runs it to the end). On it:

- :func:`drive` — a closed-loop trial: :func:`start_trial` puts the vehicle on the plan's
  first pose with its :class:`MPPIPolicy` (MPPI at 20 Hz, :data:`MPPI_DT_S`), then the
  loop runs to the outcome, success within 5 m of the goal (the paper's rule);
- :func:`follow_path` / :func:`drive_straight` — scripted drives (pure pursuit, or a
  fixed command) that record every control step, for the physical premises.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace

import numpy as np

from dgt_lib.core.controller import MPPIConfig
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.navigation.control.bicycle import rear_axle_pose, steering_from_twist
from dgt_lib.navigation.control.mppi import MPPIController
from dgt_lib.navigation.control.mppi_config import vehicle_footprint
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


@dataclass(frozen=True)
class DriveStep:
    """One control period of a drive: the ``state`` judged, the rule's ``outcome`` (None
    while the drive goes on) and, when it goes on, the command sent (``speed_cmd`` [m/s],
    ``steer`` ∈ [−1, 1])."""

    state: VehicleState
    outcome: TrialOutcome | None
    speed_cmd: float = math.nan
    steer: float = math.nan


def drive_steps(sim: Simulator, policy: Policy, rule: OutcomeRule, *, goal=None,
                dt_s: float = CONTROL_DT_S) -> Iterator[DriveStep]:
    """The drive loop, one :class:`DriveStep` at a time: from the simulator's current
    state, judge it with ``rule`` (the first state included); once the rule decides,
    yield the verdict and end; else ask ``policy`` for a command, yield it, and step the
    simulator ``dt_s`` [s] with it. Stepping it by hand (a notebook) drives the very
    trial :func:`drive` drives."""
    goal = None if goal is None else np.asarray(goal, float)[:2]
    state = sim.state
    while True:
        outcome = rule.judge(state.time_s, state.position, goal, state.immobilized_s,
                             state.done_reason)
        if outcome is not None:
            yield DriveStep(state, outcome)
            return
        speed, steer = policy(state)
        yield DriveStep(state, None, float(speed), float(steer))
        state = sim.step(speed_cmd_mps=float(speed), steer=float(steer), duration_s=dt_s)


def drive_loop(sim: Simulator, policy: Policy, rule: OutcomeRule, *, goal=None,
               dt_s: float = CONTROL_DT_S,
               on_state: Callable[[VehicleState], None] | None = None) -> TrialOutcome:
    """Run :func:`drive_steps` until ``rule`` decides; ``on_state`` sees every state.
    Returns the outcome; the simulator holds the last state."""
    for step in drive_steps(sim, policy, rule, goal=goal, dt_s=dt_s):
        if on_state is not None:
            on_state(step.state)
        if step.outcome is not None:
            return step.outcome
    raise AssertionError("drive_steps ends with an outcome")


class MPPIPolicy:
    """The trials' policy: MPPI on the rear-axle pose (the planner's path moved there),
    its twist (v_x, ω_z) turned into a steering command by the bicycle relation
    δ = atan(ℓ ω_z / v_x), normalised by δ_max (paper: Controller Integration).
    ``controller`` is the :class:`MPPIController` (its ``optimal_trajectory`` the plan
    of the last call); ``on_command(state, v_x, steer)`` sees every command. A directional
    ``costmap`` (K, H, W) on ``grid`` feeds the terrain critic (``cfg.terrain_weight``)."""

    def __init__(self, spec: VehicleSpec, path: np.ndarray, cfg: MPPIConfig, *, seed: int = 0,
                 occupancy=None, grid=None,
                 on_command: Callable[[VehicleState, float, float], None] | None = None,
                 costmap=None):
        self.spec, self.occupancy, self.grid, self.on_command = spec, occupancy, grid, on_command
        self.costmap = costmap
        self.controller = MPPIController.from_vehicle(spec, cfg, seed=seed)
        # the controller works on the rear-axle centre, the planner on the body centre
        self.controller.set_path(rear_axle_pose(path[:, :2], path[:, 2], spec.wheelbase_m))

    def __call__(self, state: VehicleState) -> tuple[float, float]:
        spec = self.spec
        pose = rear_axle_pose(state.position, state.yaw, spec.wheelbase_m)
        v_x, w_z = self.controller.compute(pose, state.speed_mps, self.occupancy, self.grid,
                                           self.costmap)
        steer = steering_from_twist(v_x, w_z, spec.wheelbase_m, spec.max_steer_rad)
        if self.on_command is not None:
            self.on_command(state, v_x, steer)
        return v_x, steer


def trial_mppi_config(spec: VehicleSpec, mppi: MPPIConfig | None = None) -> MPPIConfig:
    """The MPPI settings a trial of ``spec`` runs: ``mppi`` (a profile's ``mppi`` section;
    default the paper's) with the vehicle's footprint (:func:`vehicle_footprint`)."""
    return replace(mppi or MPPIConfig(), **vehicle_footprint(spec))


def start_trial(sim: Simulator, path: np.ndarray, *, occupancy=None, grid=None,
                mppi: MPPIConfig | None = None, seed: int = 0,
                on_command: Callable[[VehicleState, float, float], None] | None = None,
                costmap=None, start_pose: Sequence[float] | None = None) -> Policy:
    """Put the simulated vehicle on ``path``'s first pose, or on ``start_pose`` (x [m],
    y [m], yaw [rad]: a vehicle pushed off its plan), and return the trial's policy:
    :class:`MPPIPolicy` tracking the path (``costmap``: for the terrain critic), or
    holding still when the path is one pose (nothing to track)."""
    path = np.asarray(path, float)
    x, y, yaw = (float(v) for v in (path[0] if start_pose is None else start_pose))
    sim.reset(x, y, yaw)
    if not _has_length(path):
        return lambda state: (0.0, 0.0)  # hold still: nothing to track
    cfg = trial_mppi_config(sim.vehicle, mppi)
    return MPPIPolicy(sim.vehicle, path, cfg, seed=seed, occupancy=occupancy, grid=grid,
                      on_command=on_command, costmap=costmap)


def drive(world: World, vehicle: str, path: np.ndarray, goal, *, occupancy=None, grid=None,
          time_limit_s: float, mppi: MPPIConfig | None = None, seed: int = 0,
          on_command: Callable[[VehicleState, float, float], None] | None = None,
          costmap=None, start_pose: Sequence[float] | None = None
          ) -> tuple[TrialOutcome, np.ndarray, np.ndarray]:
    """Track ``path`` (N, 3) in MuJoCo with MPPI at 20 Hz from its first pose.

    Returns (outcome, trajectory (T, 4) [t, x, y, z] every :data:`LOG_DT_S`, speed (T,)).
    Judged by :class:`OutcomeRule` with the paper's 5 m and 10 s and ``time_limit_s``.
    A path of one pose (the planner's answer when the start is already within its goal
    tolerance) has nothing to track: the vehicle holds still and the rule judges where
    it stands (success at t = 0 when that is within 5 m of the goal).
    ``on_command(state, speed_cmd [m/s], steer ∈ [−1, 1] of the steering lock)`` sees every
    command MPPI gives, with the state it answered (``studies/replay_trial.py`` prints
    them). ``mppi``: the MPPI settings (a profile's ``mppi`` section, e.g.
    ``replace(profile.mppi, lateral_accel_max=2.0)`` in ``studies/controller_variants.py``;
    default the paper's). ``costmap``: the plan's directional costmap (K, H, W) on ``grid``,
    paid by every rollout when ``mppi.terrain_weight`` > 0 (the terrain
    critic, docs/controller.md; the experiments pass the method's own with
    ``experiments.controller=terrain``). ``start_pose`` (x, y, yaw): start there instead
    of on the path (``studies/off_plan.py``). The same as
    :func:`start_trial` then :func:`drive_steps` to the end.
    """
    sim = Simulator(world, get_vehicle(vehicle))
    try:
        policy = start_trial(sim, path, occupancy=occupancy, grid=grid,
                             mppi=mppi, seed=seed, on_command=on_command,
                             costmap=costmap, start_pose=start_pose)
        rows, speeds = [], []
        next_log = 0.0
        for step in drive_steps(sim, policy, OutcomeRule(time_limit_s=time_limit_s),
                                goal=goal, dt_s=MPPI_DT_S):
            state = step.state
            if state.time_s >= next_log:
                rows.append((state.time_s, *state.position))
                speeds.append(state.speed_mps)
                next_log += LOG_DT_S
            outcome = step.outcome
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
    max_time_s: float = 120.0,
    goal_tolerance_m: float = 3.0,
    immobilized_limit_s: float = 10.0,
) -> Trajectory:
    """Drive along a (M, 2) waypoint path at ``speed_mps`` with pure pursuit and the
    PID speed controller at 25 Hz, from its first point, heading along the path, until
    within ``goal_tolerance_m`` of its last point, immobilized for
    ``immobilized_limit_s`` (paper: 10 s), a simulator ``done_reason``, or
    ``max_time_s``. ``end_reason`` is ``"goal"``, ``"timeout"``, ``"immobilized"`` or
    the simulator's ``done_reason``."""
    path = np.asarray(path_xy, np.float64)
    d0 = path[1] - path[0]
    sim.reset(path[0, 0], path[0, 1], math.atan2(d0[1], d0[0]))
    steer = PurePursuit(path, sim.vehicle)
    rule = OutcomeRule(goal_tolerance_m, immobilized_limit_s, max_time_s)
    return _record(sim, lambda st: (speed_mps, steer(st)), rule, goal=path[-1])


def drive_straight(sim: Simulator, x: float, y: float, yaw: float, *, speed_mps: float = 5.0,
                   duration_s: float = 10.0) -> Trajectory:
    """Reset at (x, y, yaw) and drive ``duration_s`` straight at a fixed speed command."""
    sim.reset(x, y, yaw)
    return _record(sim, lambda st: (speed_mps, 0.0),
                   OutcomeRule(immobilized_limit_s=math.inf, time_limit_s=duration_s))
