"""Closed-loop trials: plan with Hybrid A* on a method's costmap, drive the plan in MuJoCo
(paper: Experimental Protocol).

A trial plans on the costmap of the *mapped* world (the BEV from the survey, as the paper
plans on maps built from RGB-D), then tracks the path with MPPI until the outcome rule
decides (:mod:`dgt_lib.navigation.outcome`). All methods get identical queries, occupancy
map, planner and controller settings. Trials are independent and run through any
``concurrent.futures.Executor`` (:func:`~dgt_lib.core.executors.run_jobs`); a trial that
raises is recorded as ``error`` with its traceback and the run goes on. Every finished
trial is journaled (:mod:`dgt_lib.evaluation.journal`).

A worker needs the costmaps of its world: :func:`run_trials` takes ``load_maps`` — a
picklable function ``(world, method, vehicle, profile) -> WorldMaps`` (the stages layer
passes one that reads the artifact cache).
"""

from __future__ import annotations

import math
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from dgt_lib.core.config import ExperimentsConfig, Profile
from dgt_lib.core.executors import run_jobs
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.evaluation.journal import Journal, read_journal
from dgt_lib.evaluation.queries import Query, classify_route
from dgt_lib.mapping.baselines import binary_costmap
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.navigation.drive import MPPI_DT_S, DriveStep, drive, drive_steps, start_trial
from dgt_lib.navigation.outcome import OutcomeRule, TrialOutcome
from dgt_lib.navigation.planner import HybridAStar
from dgt_lib.world.simulator import Simulator
from dgt_lib.world.terrain import get_world

MapsLoader = Callable[[str, str, str, Profile], WorldMaps]
"""(world, method, vehicle, profile) → the :class:`WorldMaps` holding that costmap."""


@dataclass(frozen=True)
class TrialTask:
    """Everything a worker needs to run one trial (small, picklable). ``profile`` is the
    whole :class:`Profile` — customised settings travel with the task."""

    experiment: str
    world: str
    method: str
    vehicle: str
    query: Query
    index: int
    profile: Profile
    seed: int


@dataclass
class TrialResult:
    """One trial: the plan, the executed trajectory and how it ended.

    path: (N, 3) planned poses; trajectory: (T, 4) t [s], x, y, z [m] sampled every
    LOG_DT_S; speed: (T,) [m/s]; route: which way the plan went (world-specific,
    e.g. hill "A"/"B", ridge "sharp"/"smooth"), or "" without a plan.
    """

    task: TrialTask
    outcome: TrialOutcome
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    plan_cost: float = math.inf
    plan_time_s: float = 0.0
    expansions: int = 0
    route: str = ""
    trajectory: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    speed: np.ndarray = field(default_factory=lambda: np.zeros(0))
    wall_s: float = 0.0


def trial_time_limit_s(cfg: ExperimentsConfig, path_length_m: float) -> float:
    """A trial's time limit [s]: base + factor × the time to drive the plan at 5 m/s."""
    return cfg.time_limit_base_s + cfg.time_limit_factor * path_length_m / 5.0


def trial_tasks(experiment: str, world: str, vehicle: str, queries: Sequence[Query],
                methods: Sequence[str], profile: Profile) -> list[TrialTask]:
    """One task per query and method; query i's controller seed is ``profile.seed + i``."""
    return [TrialTask(experiment, world, m, vehicle, q, i, profile, profile.seed + i)
            for i, q in enumerate(queries) for m in methods]


def method_costmap(maps: WorldMaps, method: str, vehicle: str) -> np.ndarray:
    """The directional costmap (K, H, W) a method's trials plan on (Binary's: zeros)."""
    if method == "binary" and ("binary", vehicle) not in maps.costmaps:
        return binary_costmap(maps.grid.shape)
    return maps.costmap(method, vehicle)


@lru_cache(maxsize=16)
def _planner(world: str, method: str, vehicle: str, profile: Profile,
             load_maps: MapsLoader) -> tuple[HybridAStar, WorldMaps, np.ndarray]:
    """The planner of a (world, method, vehicle), built once per process, its maps and the
    costmap it plans on (Binary's: zeros)."""
    maps = load_maps(world, method, vehicle, profile)
    cost = method_costmap(maps, method, vehicle)
    return HybridAStar.for_vehicle(cost, maps.occupancy, maps.grid, get_vehicle(vehicle),
                                   profile.planner), maps, cost


def trial_controller(prof: Profile, costmap: np.ndarray) -> dict[str, object]:
    """``drive``'s controller arguments: the profile's ``mppi`` section (the preset
    ``experiments.controller`` names, :mod:`dgt_lib.core.controller`) and, when its terrain
    critic is on (``mppi.terrain_weight`` > 0), the method's own ``costmap`` (K, H, W)."""
    out: dict[str, object] = {"mppi": prof.mppi}
    return {**out, "costmap": costmap} if prof.mppi.terrain_weight > 0 else out


def run_trial(task: TrialTask, load_maps: MapsLoader) -> TrialResult:
    """Plan and drive one trial; never raises (an exception becomes an ``error`` outcome)."""
    t0 = time.perf_counter()
    try:
        prof = task.profile
        world = get_world(task.world, prof)
        planner, maps, cost = _planner(task.world, task.method, task.vehicle, prof, load_maps)
        plan = planner.plan(task.query.start, task.query.goal)
        if not plan.success:
            return TrialResult(task, TrialOutcome.failure("no_path", detail=plan.reason),
                               plan_time_s=plan.time_s, expansions=plan.expansions,
                               wall_s=time.perf_counter() - t0)
        outcome, traj, speed = drive(world, task.vehicle, plan.path, task.query.goal,
                                     occupancy=maps.occupancy, grid=maps.grid,
                                     time_limit_s=trial_time_limit_s(prof.experiments,
                                                                     plan.length_m),
                                     seed=task.seed, **trial_controller(prof, cost))
        return TrialResult(task, outcome, plan.path, plan.cost, plan.time_s, plan.expansions,
                           classify_route(world, plan.path), traj, speed,
                           time.perf_counter() - t0)
    except Exception as exc:  # noqa: BLE001 - a crashed trial is a recorded result
        detail = "".join(traceback.format_exception(exc))
        return TrialResult(task, TrialOutcome.failure("error", detail=detail),
                           wall_s=time.perf_counter() - t0)


def step_trial(result: TrialResult, maps: WorldMaps, *, keep_every: int = 60
               ) -> tuple[list[DriveStep], dict[float, np.ndarray], OutcomeRule]:
    """Drive a recorded trial's plan again as :func:`run_trial` did (its controller, seed
    and time limit), one 50 ms control period at a time: for a notebook to look inside.

    Returns every :class:`~dgt_lib.navigation.drive.DriveStep`, MPPI's predicted
    trajectory (T, ≥ 2) [m] every ``keep_every`` periods keyed by the time [s], and the
    outcome rule that judged the steps."""
    task = result.task
    prof = task.profile
    length_m = float(np.hypot(*np.diff(result.path[:, :2], axis=0).T).sum())
    rule = OutcomeRule(time_limit_s=trial_time_limit_s(prof.experiments, length_m))
    sim = Simulator(get_world(task.world, prof), task.vehicle)
    try:
        cost = method_costmap(maps, task.method, task.vehicle)
        policy = start_trial(sim, result.path, occupancy=maps.occupancy, grid=maps.grid,
                             seed=task.seed, **trial_controller(prof, cost))
        steps, plans = [], {}
        for step in drive_steps(sim, policy, rule, goal=task.query.goal, dt_s=MPPI_DT_S):
            steps.append(step)
            if len(steps) % keep_every == 1 and hasattr(policy, "controller"):
                plans[step.state.time_s] = policy.controller.optimal_trajectory.copy()
    finally:
        sim.close()
    return steps, plans, rule


def _start_method() -> str:
    """``fork`` (workers start in milliseconds) unless this process has initialised CUDA,
    which a forked child cannot use: then ``spawn``."""
    torch = sys.modules.get("torch")
    return "spawn" if torch is not None and torch.cuda.is_initialized() else "fork"


def run_trials(tasks: Sequence[TrialTask], load_maps: MapsLoader,
               executor: Executor | None = None, *, workers: int = 2, progress: bool = True,
               journal: str | Path | None = None, backend: str = "process",
               address: str | None = None) -> list[TrialResult]:
    """Run trials in parallel, with a progress bar; results come back in task order.

    executor: default that of an enclosing :func:`~dgt_lib.core.executors.use_executor`
    block, else ``backend`` at ``address`` (a process pool of ``workers``, or a Dask
    cluster, :func:`~dgt_lib.core.executors.run_jobs`). The results do not depend on
    it. A worker calls ``load_maps``: with :func:`dgt_lib.stages.experiments.trial_maps`,
    cluster workers must see this machine's data directory (``DGT_DATA_DIR``, a shared
    file system on a multi-machine cluster).

    journal: a file to which every trial is appended as soon as it ends. Trials
    already in it are not run again (those that ended in ``error`` are retried), so
    an experiment stopped by Ctrl-C or a crash resumes where it stopped.
    """
    done = {} if journal is None else {
        t: r for t, r in read_journal(journal).items() if r.outcome.reason != "error"}
    done = {t: done[t] for t in tasks if t in done}
    todo = [t for t in tasks if t not in done]
    log = Journal(journal) if journal is not None and todo else None

    def keep(job: tuple, result: TrialResult) -> None:
        done[result.task] = result
        if log is not None:
            log.append(result)

    try:
        run_jobs(run_trial, [(t, load_maps) for t in todo], executor=executor,
                 workers=workers, start_method=_start_method(), backend=backend,
                 address=address, on_result=keep,
                 progress=progress,
                 desc="trials", unit="trial", initial=len(done),
                 postfix=lambda: f"{sum(r.outcome.success for r in done.values())}/"
                                 f"{len(done)} ok")
    finally:
        if log is not None:
            log.close()
    return [done[t] for t in tasks]
