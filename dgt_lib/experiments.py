"""Closed-loop trials and the paper's three experiments (paper: Experiments, Results).

A trial plans with Hybrid A* on a method's costmap of the *mapped* world (the BEV
from the survey, as the paper plans on maps built from RGB-D), then drives the
path in MuJoCo with the MPPI tracker until success (within 5 m of the goal) or
failure: immobilized > 10 s, flipped, off the map, time-out, or no path. All
methods get identical start–goal queries, occupancy map, planner and controller
settings (paper: Experimental Protocol).

* Experiment 1 — hill, carla_cola, ascents and descents: does the planner pick
  Route A uphill and Route B downhill?
* Experiment 2 — ridge, mercedes_van: does it cross at the smoothed section?
* Experiment 3 — eval world, random start–goal pairs, jeep and vw_van:
  multi-task vs single-task.

Trials are independent and run through a ``concurrent.futures.Executor`` (a
process pool by default); a trial that raises is recorded as ``error`` with its
traceback and the run goes on.
"""

from __future__ import annotations

import math
import pickle
import time
import traceback
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from . import artifacts
from .config import ExperimentsConfig, Profile, get_profile
from .control import (
    MPPIConfig,
    MPPIController,
    rear_axle_pose,
    steering_from_twist,
    vehicle_footprint,
)
from .geometry import wrap_angle
from .inference import METHOD_LABELS, METHODS, WorldMaps, ensure_world_costmaps
from .outcomes import (
    PAPER_TABLE_I,
    PAPER_TABLE_II,
    ImmobilityMonitor,
    TrialOutcome,
    markdown_table,
    reason_counts,
    success_rows,
)
from .pipeline import StageOutput
from .planner import HybridAStar
from .vehicles import get_vehicle
from .worlds import World, get_world, polyline_distance

OUTCOME_KEYS = {"dgt": "dgt_map", "isotropic": "dgt_map_iso", "single-task": "dgt_map_st",
                "slope": "slope_based", "binary": "binary"}
"""Our method names → the keys of the paper's numbers in ``dgt_lib.outcomes``."""
CONTROL_DT_S = 0.05  # MPPI rate 20 Hz (Nav2 model_dt)
LOG_DT_S = 0.25  # trajectory samples kept per trial [s]


@dataclass(frozen=True)
class Query:
    """A start pose (x [m], y [m], yaw [rad]) and a goal (x, y) [m], with a label
    (e.g. "ascent"/"descent") shared by every method."""

    start: tuple[float, float, float]
    goal: tuple[float, float]
    label: str = ""


@dataclass(frozen=True)
class TrialTask:
    """Everything a worker needs to run one trial (small, picklable)."""

    experiment: str
    world: str
    method: str
    vehicle: str
    query: Query
    index: int
    profile: str
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


# ----------------------------------------------------------------------------- queries
def _jitter(rng: np.random.Generator, xy, sigma_m: float) -> tuple[float, float]:
    d = rng.uniform(-sigma_m, sigma_m, 2)
    return float(xy[0] + d[0]), float(xy[1] + d[1])


def _heading(rng, base_rad: float, jitter_deg: float) -> float:
    return float(wrap_angle(base_rad + np.radians(rng.uniform(-jitter_deg, jitter_deg))))


def hill_queries(world: World, n: int, cfg: ExperimentsConfig, seed: int) -> list[Query]:
    """n queries alternating ascent (base → summit) and descent (summit → base).

    Ascents start facing north-east, between Route A (east) and Route B (north), so
    the start heading favours neither; descents start facing south-east likewise.
    """
    rng = np.random.default_rng(seed)
    base, summit = world.landmarks["base"], world.landmarks["summit"]
    out = []
    for i in range(n):
        if i % 2 == 0:
            out.append(Query((*_jitter(rng, base, cfg.start_jitter_m),
                              _heading(rng, np.pi / 4, cfg.heading_jitter_deg)),
                             _jitter(rng, summit, cfg.start_jitter_m), "ascent"))
        else:
            out.append(Query((*_jitter(rng, summit, cfg.start_jitter_m),
                              _heading(rng, -np.pi / 4, cfg.heading_jitter_deg)),
                             _jitter(rng, base, cfg.start_jitter_m), "descent"))
    return out


def ridge_queries(world: World, n: int, cfg: ExperimentsConfig, seed: int) -> list[Query]:
    """n queries alternating south → north and north → south across the ridge."""
    rng = np.random.default_rng(seed)
    south, north = world.landmarks["south"], world.landmarks["north"]
    out = []
    for i in range(n):
        a, b, yaw, label = ((south, north, np.pi / 2, "northbound") if i % 2 == 0
                            else (north, south, -np.pi / 2, "southbound"))
        out.append(Query((*_jitter(rng, a, cfg.start_jitter_m),
                          _heading(rng, yaw, cfg.heading_jitter_deg)),
                         _jitter(rng, b, cfg.start_jitter_m), label))
    return out


def random_queries(maps: WorldMaps, n: int, cfg: ExperimentsConfig, seed: int,
                   vehicle: str) -> list[Query]:
    """n random start–goal pairs on free cells of the occupancy map, their distance
    in ``cfg.eval_distance_m``, start heading uniform; both must be valid planner
    queries for ``vehicle`` (no footprint collision) — otherwise resampled."""
    rng = np.random.default_rng(seed)
    planner = _planner_for(maps, "binary", vehicle)
    x0, x1, y0, y1 = maps.grid.extent
    lo, hi = cfg.eval_distance_m
    out: list[Query] = []
    for _ in range(200 * max(n, 1)):
        if len(out) == n:
            break
        sx, sy = rng.uniform(x0 + 10, x1 - 10), rng.uniform(y0 + 10, y1 - 10)
        ang, dist = rng.uniform(0, 2 * np.pi), rng.uniform(lo, hi)
        gx, gy = sx + dist * np.cos(ang), sy + dist * np.sin(ang)
        if not (x0 + 10 < gx < x1 - 10 and y0 + 10 < gy < y1 - 10):
            continue
        start = (float(sx), float(sy), float(rng.uniform(0, 2 * np.pi)))
        goal_poses = [(gx, gy, th) for th in np.linspace(0, 2 * np.pi, 8, endpoint=False)]
        if planner.collides(start)[0] or planner.collides(np.array(goal_poses)).all():
            continue
        out.append(Query(start, (float(gx), float(gy)), "random"))
    if len(out) < n:
        raise RuntimeError(f"found only {len(out)} of {n} valid random queries on {maps.world}")
    return out


# ----------------------------------------------------------------------------- routes
RIDGE_SMOOTH_HALF_WIDTH_M = 9.0
"""Half-width of the ridge's smoothed section around ``smooth_crossing`` [m] (worlds.make_ridge)."""


def classify_route(world: World, path: np.ndarray, tolerance_m: float = 6.0) -> str:
    """Which way a planned path went, "" for worlds without routes.

    Hill: the route whose polyline is closest on average ("A" or "B"), "other" when
    even that one is farther than ``tolerance_m`` on average. Ridge: where the path
    crosses the ridge line — "smooth" within the smoothed section, else "sharp" (the
    ridge is sharp everywhere else, across the whole map).
    """
    if len(path) == 0:
        return ""
    xy = np.asarray(path, dtype=float)[:, :2]
    if world.name == "hill":
        mean_d = {key: float(polyline_distance(xy, world.routes[key])[0].mean())
                  for key in ("A", "B")}
        best = min(mean_d, key=mean_d.get)
        return best if mean_d[best] <= tolerance_m else "other"
    if world.name == "ridge":
        y_ridge = world.landmarks["sharp_crossing"][1]
        x_cross = xy[int(np.argmin(np.abs(xy[:, 1] - y_ridge))), 0]
        smooth_x = world.landmarks["smooth_crossing"][0]
        return "smooth" if abs(x_cross - smooth_x) <= RIDGE_SMOOTH_HALF_WIDTH_M else "sharp"
    return ""


# ----------------------------------------------------------------------------- one trial
@lru_cache(maxsize=16)
def _maps(world: str, method: str, vehicle: str, profile: str) -> WorldMaps:
    return ensure_world_costmaps(world, (vehicle,), profile, methods=(method,), progress=False)


def _planner_for(maps: WorldMaps, method: str, vehicle: str, cfg=None) -> HybridAStar:
    spec = get_vehicle(vehicle)
    if method == "binary" and ("binary", vehicle) not in maps.costmaps:
        from .baselines import binary_costmap

        cost = binary_costmap(maps.grid.shape)
    else:
        cost = maps.costmap(method, vehicle)
    return HybridAStar(cost, maps.occupancy, maps.grid, min_turn_radius_m=spec.centre_turn_radius_m,
                       footprint=(spec.length_m, spec.width_m), cfg=cfg)


@lru_cache(maxsize=16)
def _cached_planner(world: str, method: str, vehicle: str, profile: str) -> HybridAStar:
    return _planner_for(_maps(world, method, vehicle, profile), method, vehicle,
                        get_profile(profile).planner)


def drive(world: World, vehicle: str, path: np.ndarray, goal, *, occupancy=None, grid=None,
          time_limit_s: float, mppi_batch_size: int = 1000, seed: int = 0):
    """Track ``path`` (N, 3) in MuJoCo with MPPI at 20 Hz from its first pose.

    Returns (outcome, trajectory (T, 4) [t, x, y, z], speed (T,)). Success when
    within 5 m of ``goal``; failures: immobilized > 10 s, flipped, off the map or
    a simulator divergence ("diverged"), time-out at ``time_limit_s``.
    """
    from .sim import Simulator

    spec = get_vehicle(vehicle)
    sim = Simulator(world, spec)
    try:
        x, y, yaw = (float(v) for v in path[0])
        state = sim.reset(x, y, yaw)
        cfg = replace(MPPIConfig(batch_size=mppi_batch_size), **vehicle_footprint(spec))
        ctrl = MPPIController.from_vehicle(spec, cfg, seed=seed)
        # the controller works on the rear-axle centre, the planner on the body centre
        ctrl.set_path(rear_axle_pose(path[:, :2], path[:, 2], spec.wheelbase_m))
        monitor = ImmobilityMonitor()
        goal = np.asarray(goal, float)[:2]
        rows, speeds = [], []
        next_log = 0.0
        outcome = None
        while outcome is None:
            t = state.time_s
            if t >= next_log:
                rows.append((t, *state.position))
                speeds.append(state.speed_mps)
                next_log += LOG_DT_S
            dist = float(np.hypot(*(state.position[:2] - goal)))
            if dist < 5.0:
                outcome = TrialOutcome(True, "success", t, dist)
            elif state.done_reason is not None:
                reason = "flipped" if state.done_reason == "flipped" else "diverged"
                outcome = TrialOutcome.failure(reason, t, dist, detail=state.done_reason)
            elif monitor.update(t, state.speed_mps):
                outcome = TrialOutcome.failure("immobilized", t, dist)
            elif t >= time_limit_s:
                outcome = TrialOutcome.failure("timeout", t, dist)
            else:
                pose = rear_axle_pose(state.position, state.yaw, spec.wheelbase_m)
                v_x, w_z = ctrl.compute(pose, state.speed_mps, occupancy, grid)
                steer = steering_from_twist(v_x, w_z, spec.wheelbase_m, spec.max_steer_rad)
                state = sim.step(speed_cmd_mps=float(v_x), steer=float(steer),
                                 duration_s=CONTROL_DT_S)
        rows.append((state.time_s, *state.position))
        speeds.append(state.speed_mps)
        return outcome, np.asarray(rows, float), np.asarray(speeds, float)
    finally:
        sim.close()


def run_trial(task: TrialTask) -> TrialResult:
    """Plan and drive one trial; never raises (an exception becomes an ``error`` outcome)."""
    t0 = time.perf_counter()
    try:
        prof = get_profile(task.profile)
        world = get_world(task.world, prof)
        maps = _maps(task.world, task.method, task.vehicle, task.profile)
        planner = _cached_planner(task.world, task.method, task.vehicle, task.profile)
        plan = planner.plan(task.query.start, task.query.goal)
        if not plan.success:
            return TrialResult(task, TrialOutcome.failure("no_path", detail=plan.reason),
                               plan_time_s=plan.time_s, expansions=plan.expansions,
                               wall_s=time.perf_counter() - t0)
        limit = prof.experiments.time_limit_base_s + (
            prof.experiments.time_limit_factor * plan.length_m / 5.0)
        outcome, traj, speed = drive(world, task.vehicle, plan.path, task.query.goal,
                                     occupancy=maps.occupancy, grid=maps.grid,
                                     time_limit_s=limit,
                                     mppi_batch_size=prof.experiments.mppi_batch_size,
                                     seed=task.seed)
        return TrialResult(task, outcome, plan.path, plan.cost, plan.time_s, plan.expansions,
                           classify_route(world, plan.path), traj, speed,
                           time.perf_counter() - t0)
    except Exception as exc:  # noqa: BLE001 - a crashed trial is a recorded result
        detail = "".join(traceback.format_exception(exc))
        return TrialResult(task, TrialOutcome.failure("error", detail=detail),
                           wall_s=time.perf_counter() - t0)


def read_journal(path: str | Path) -> dict[TrialTask, TrialResult]:
    """The finished trials recorded in a journal file by :func:`run_trials`, by task.

    A record cut short by a crash (the last one) is ignored; a missing file is empty.
    """
    done: dict[TrialTask, TrialResult] = {}
    path = Path(path)
    if not path.exists():
        return done
    with open(path, "rb") as f:
        while True:
            try:
                result = pickle.load(f)
            except (EOFError, pickle.UnpicklingError, AttributeError, ValueError):
                break  # end of file, or a half-written last record
            done[result.task] = result
    return done


def run_trials(tasks: Sequence[TrialTask], executor: Executor | None = None, *,
               workers: int = 2, progress: bool = True,
               journal: str | Path | None = None) -> list[TrialResult]:
    """Run trials in parallel (process pool of ``workers`` unless an executor is given),
    with a progress bar; results come back in task order.

    journal: a file to which every trial is appended as soon as it ends. Trials
    already in it are not run again (those that ended in ``error`` are retried), so
    an experiment stopped by Ctrl-C or a crash resumes where it stopped.
    """
    from concurrent.futures import ProcessPoolExecutor, as_completed

    from tqdm.auto import tqdm

    from .collect import limit_threads

    done = {} if journal is None else {
        t: r for t, r in read_journal(journal).items() if r.outcome.reason != "error"}
    done = {t: done[t] for t in tasks if t in done}
    todo = [t for t in tasks if t not in done]
    own = executor is None and len(todo) > 0
    if own:
        executor = ProcessPoolExecutor(max_workers=workers, initializer=limit_threads)
    log = None
    if journal is not None:
        Path(journal).parent.mkdir(parents=True, exist_ok=True)
        log = open(journal, "ab")
    bar = tqdm(total=len(tasks), initial=len(tasks) - len(todo), desc="trials", unit="trial",
               disable=not progress)
    try:
        futures = [executor.submit(run_trial, t) for t in todo]
        n_ok = sum(r.outcome.success for r in done.values())
        for fut in as_completed(futures):
            result = fut.result()
            done[result.task] = result
            if log is not None:
                pickle.dump(result, log)
                log.flush()
            n_ok += result.outcome.success
            bar.update()
            bar.set_postfix_str(f"{n_ok}/{bar.n} ok")
        return [done[t] for t in tasks]
    finally:
        bar.close()
        if log is not None:
            log.close()
        if own:
            executor.shutdown(cancel_futures=True)


# ----------------------------------------------------------------------------- experiments
@dataclass
class ExperimentResult:
    """All trials of an experiment, with their tables."""

    name: str
    world: str
    results: list[TrialResult]

    def counts(self, vehicle: str | None = None, label: str | None = None
               ) -> dict[str, tuple[int, int]]:
        """{method: (k, n)} in the paper's method order."""
        out = {}
        for m in METHODS:
            rs = [r for r in self.results if r.task.method == m
                  and (vehicle is None or r.task.vehicle == vehicle)
                  and (label is None or r.task.query.label == label)]
            if rs:
                out[m] = (sum(r.outcome.success for r in rs), len(rs))
        return out

    def table(self, vehicle: str, paper=None) -> str:
        """A markdown table like the paper's (k, n, SR %) with Wilson 95 % intervals and,
        when given, the paper's numbers beside ours."""
        counts = {OUTCOME_KEYS[m]: kn for m, kn in self.counts(vehicle).items()}
        rows = success_rows(counts, paper=None if paper is None else dict(paper.k),
                            paper_n=None if paper is None else paper.n)
        return markdown_table(rows, title=f"{self.name}: {vehicle}")

    def routes(self) -> dict[tuple[str, str], dict[str, int]]:
        """{(method, label): {route: count}} — which way each method planned."""
        out: dict[tuple[str, str], dict[str, int]] = {}
        for r in self.results:
            d = out.setdefault((r.task.method, r.task.query.label), {})
            route = r.route or ("no path" if len(r.path) == 0 else "—")
            d[route] = d.get(route, 0) + 1
        return out

    def reasons(self) -> dict[str, dict[str, int]]:
        """{method: {reason: count}}."""
        return {m: reason_counts(r.outcome for r in self.results if r.task.method == m)
                for m in METHODS if any(r.task.method == m for r in self.results)}

    def route_markdown(self) -> str:
        """Markdown table: the routes each method planned, per query label."""
        lines = ["| method | query | planned routes |", "|---|---|---|"]
        for (m, label), d in sorted(self.routes().items(),
                                    key=lambda kv: (METHODS.index(kv[0][0]), kv[0][1])):
            lines.append(f"| {METHOD_LABELS[m]} | {label} | "
                         + ", ".join(f"{k}: {v}" for k, v in sorted(d.items())) + " |")
        return "\n".join(lines) + "\n"

    def reason_markdown(self) -> str:
        """Markdown table: how the trials of each method ended."""
        reasons = self.reasons()
        names = list(next(iter(reasons.values()), {}))
        lines = ["| method | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
        for m, d in reasons.items():
            lines.append(f"| {METHOD_LABELS[m]} | " + " | ".join(str(v) for v in d.values())
                         + " |")
        return "\n".join(lines) + "\n"

    def markdown(self, paper: dict | None = None) -> str:
        """Tables (ours beside the paper's), routes and failure reasons as markdown."""
        vehicles = sorted({r.task.vehicle for r in self.results})
        parts = [self.table(v, (paper or {}).get(v)) for v in vehicles]
        if any(r.route for r in self.results):
            parts.append(self.route_markdown())
        return "\n".join(parts + [self.reason_markdown()])


def _tasks(experiment: str, world: str, vehicle: str, queries: list[Query],
           methods: Sequence[str], prof: Profile) -> list[TrialTask]:
    return [TrialTask(experiment, world, m, vehicle, q, i, prof.name, prof.seed + i)
            for i, q in enumerate(queries) for m in methods]


def run_experiment(name: str, profile: Profile | str | None = None, *,
                   executor: Executor | None = None, progress: bool = True,
                   methods: Sequence[str] | None = None,
                   journal: str | Path | None = None) -> ExperimentResult:
    """Run experiment ``"experiment1"`` (hill), ``"experiment2"`` (ridge) or
    ``"experiment3"`` (eval, random pairs) at the profile's n.

    journal: see :func:`run_trials` (finished trials are kept there; a rerun resumes).
    """
    prof = profile if isinstance(profile, Profile) else get_profile(profile)
    ex = prof.experiments
    if name == "experiment1":
        world, vehicles = "hill", ("carla_cola",)
        methods = tuple(methods or METHODS)
        queries = {"carla_cola": hill_queries(get_world(world, prof), ex.n_hill, ex, prof.seed)}
    elif name == "experiment2":
        world, vehicles = "ridge", ("mercedes_van",)
        methods = tuple(methods or METHODS)
        queries = {"mercedes_van": ridge_queries(get_world(world, prof), ex.n_ridge, ex,
                                                 prof.seed)}
    elif name == "experiment3":
        world, vehicles = "eval", ("jeep", "vw_van")
        methods = tuple(methods or ("dgt", "single-task"))
        queries = {}
        for v, n in zip(vehicles, (ex.n_eval_jeep, ex.n_eval_vw_van), strict=True):
            maps = ensure_world_costmaps(world, (v,), prof, methods=("binary",), progress=False)
            queries[v] = random_queries(maps, n, ex, prof.seed, v)
    else:
        raise ValueError(f"unknown experiment {name!r}; valid: experiment1, experiment2, "
                         "experiment3")
    # build every costmap in this process first, so workers only load them
    ensure_world_costmaps(world, vehicles, prof, methods=tuple(methods), progress=progress)
    tasks = [t for v in vehicles for t in _tasks(name, world, v, queries[v], methods, prof)]
    results = run_trials(tasks, executor, workers=prof.workers, progress=progress,
                         journal=journal)
    return ExperimentResult(name, world, results)


PAPER = {"experiment1": {"carla_cola": PAPER_TABLE_I["hill"]},
         "experiment2": {"mercedes_van": PAPER_TABLE_I["ridge"]},
         "experiment3": {"jeep": PAPER_TABLE_II["jeep"], "vw_van": PAPER_TABLE_II["vw_van"]}}


def ensure_experiment(name: str, profile: Profile | str | None = None, *,
                      progress: bool = True) -> ExperimentResult:
    """An experiment's results through the cache (``experiments/<name>.pkl``), with its
    rerun recording at ``runs/<name>.rrd`` and a markdown report at ``results/<name>.md``."""
    prof = profile if isinstance(profile, Profile) else get_profile(profile)
    cfg = {"stage": name, "experiments": prof.experiments, "planner": prof.planner,
           "costmap": prof.costmap, "seed": prof.seed,
           "models": _model_digests(prof)}
    # every finished trial is journaled, so an interrupted experiment resumes
    journal = (artifacts.profile_dir(prof.name) / "experiments"
               / f"{name}.{artifacts.config_hash(cfg)}.trials.pkl")
    result = artifacts.ensure(f"experiments/{name}.pkl", cfg,
                              lambda: run_experiment(name, prof, progress=progress,
                                                     journal=journal),
                              profile=prof.name)
    for stale in journal.parent.glob(f"{name}.*.trials.pkl"):  # done, or another config's
        stale.unlink(missing_ok=True)
    world = get_world(result.world, prof)
    for r in result.results:  # routes follow the current classification rule
        r.route = classify_route(world, r.path)
    out = artifacts.profile_dir(prof.name)
    (out / "results").mkdir(parents=True, exist_ok=True)
    (out / "results" / f"{name}.md").write_text(result.markdown(PAPER.get(name)))
    rrd = out / "runs" / f"{name}.rrd"
    if not rrd.exists() or rrd.stat().st_mtime < (out / f"experiments/{name}.pkl").stat().st_mtime:
        log_experiment(result, prof, rrd)
    return result


def _model_digests(prof: Profile) -> dict[str, str | None]:
    from .train import MODEL_KINDS, model_relpath

    out = {}
    for kind in MODEL_KINDS:
        try:
            out[kind] = artifacts.stored_digest(model_relpath(kind), profile=prof.name)
        except FileNotFoundError:
            out[kind] = None
    out["slope"] = None
    try:
        out["slope"] = artifacts.stored_digest("baselines/slope_models.json", profile=prof.name)
    except FileNotFoundError:
        pass
    return out


def log_experiment(result: ExperimentResult, prof: Profile, path) -> None:
    """Write an experiment's rerun recording: terrain, costmap layers, occupancy, every
    planned path and executed trajectory (with speed) on the ``sim_time`` timeline."""
    from . import rr

    world = get_world(result.world, prof)
    vehicles = sorted({r.task.vehicle for r in result.results})
    colors = {"dgt": (0.1, 0.3, 1.0), "isotropic": (0.2, 0.8, 0.9), "single-task": (0.6, 0.2, 0.8),
              "slope": (1.0, 0.1, 0.1), "binary": (0.4, 0.4, 0.4)}
    with rr.Recording(path, result.name) as rec:
        rec.log_terrain(world.heights, world.colors, world.grid)
        maps = ensure_world_costmaps(result.world, tuple(vehicles), prof, progress=False)
        rec.log_occupancy(maps.occupancy)
        for (method, vehicle), cost in maps.costmaps.items():
            rec.log_costmap(cost, vehicle, method)
        for r in result.results:
            name = f"{r.task.method}/{r.task.vehicle}_{r.task.index}_{r.task.query.label}"
            if len(r.path):
                z = world.height_at(r.path[:, 0], r.path[:, 1]) + 0.5
                rec.log_path(name, np.column_stack([r.path[:, :2], z]),
                             colors.get(r.task.method, (1, 1, 1)))
            if len(r.trajectory):
                rec.log_trajectory(name, r.trajectory[:, 0], r.trajectory[:, 1:4],
                                   {"speed_mps": r.speed})
        rec.log_text("results", result.markdown(PAPER.get(result.name)))


def stage_experiments(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: Experiments 1–3, tables in ``results/``, runs in ``runs/``."""
    prof = profile if isinstance(profile, Profile) else get_profile(profile)
    out = artifacts.profile_dir(prof.name)
    from .report import write_results

    paths, parts, results = [], [], []
    for name in ("experiment1", "experiment2", "experiment3"):
        res = ensure_experiment(name, prof)
        results.append(res)
        paths += [out / "runs" / f"{name}.rrd"]
        counts = ", ".join(f"{METHOD_LABELS[m]} {k}/{n}" for m, (k, n) in res.counts().items())
        parts.append(f"{name}: {counts}")
    paths.insert(0, write_results(results, prof))
    return StageOutput(paths, "; ".join(parts))
