"""One planning query on a loaded world: check, costmap, plan, report, drive.

Checks the query cheapest first, so a bad start or goal costs seconds, not a training
run: against the world alone (off the map, on a tree trunk:
:func:`~dgt_lib.navigation.planner.check_query_on_world`), then against the world's
occupancy map (steep ground, unobserved terrain; needs only the BEV maps). Then it
builds the method's costmap with the profile's trained model (training first if
needed), plans with Hybrid A*, summarises the path — length, cost, time, and where it
passes high cost — saves a figure and a rerun recording named by the query
(:func:`output_stem`), and optionally drives the path in MuJoCo::

    world = worlds.from_heightmap(heights, 0.4)
    report = plan_on_world(world, get_vehicle("carla_cola"), (10, 20, 0), (90, 20))
    print(report.summary())

:mod:`dgt_lib.app.plan_one` resolves a world's name or file (height map, DEM) first.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dgt_lib.core import artifacts
from dgt_lib.core.config import Profile, as_profile, get_profile
from dgt_lib.core.faults import is_storage_error, storage_message
from dgt_lib.core.geometry import nearest_heading_bin
from dgt_lib.core.outputs import bounded_name
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.core.vehicles import is_named
from dgt_lib.evaluation.queries import classify_route
from dgt_lib.mapping.methods import METHOD_LABELS, METHODS
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.navigation.planner import HybridAStar, PlanResult, check_query_on_world
from dgt_lib.stages.costmaps import ensure_world_costmaps, world_occupancy
from dgt_lib.stages.dataset import DATASET_RELPATH
from dgt_lib.stages.paths import data_dir
from dgt_lib.stages.train import model_relpath
from dgt_lib.world.worlds import World

if TYPE_CHECKING:
    from dgt_lib.navigation.outcome import TrialOutcome  # imports the simulator: to drive

HIGH_COST = 0.5
"""Path cells with a directional cost C above this are listed in the summary."""


@dataclass
class QueryReport:
    """What one query produced: the plan, where it passes high cost, figure, recording,
    and the closed-loop outcome when driven."""

    world: str
    vehicle: str
    method: str
    start: tuple[float, float, float]
    goal: tuple[float, float]
    plan: PlanResult
    high_cost: list[tuple[float, float, float, float]] = field(default_factory=list)
    """Stretches of the path above :data:`HIGH_COST`: (x, y, θ_k [deg], max C) at their start."""
    route: str | None = None
    """Which of the world's named routes the path takes (the hill's "A" or "B", the
    ridge's "smooth" or "sharp" crossing: :func:`~dgt_lib.evaluation.queries.classify_route`);
    None on a world without routes or when no path was found."""
    figure: Path | None = None
    recording: Path | None = None
    not_written: str | None = None
    """Why the figure and recording were not written (a read-only or full directory)."""
    outcome: TrialOutcome | None = None
    never_driven: str | None = None
    """For a vehicle never driven (a file's spec), where its costmap came from."""
    warnings: list[str] = field(default_factory=list)
    """Its spec's fields outside the vehicles the kit trains on."""
    spec: VehicleSpec | None = None
    """The vehicle's spec when it is not a named one."""
    inputs: str = ""
    """What the costmap read (:func:`costmap_profile`): "geometry only (no imagery)" …"""

    def summary(self) -> str:
        p = self.plan
        lines = [f"{METHOD_LABELS[self.method]} plan for {self.vehicle} on {self.world}: "
                 f"{self.start} → {self.goal}"]
        lines += [f"  costmap input: {self.inputs}"] if self.inputs else []
        lines += [f"  {self.never_driven}"] if self.never_driven else []
        lines += [f"  warning: {w}" for w in self.warnings]
        if p.success and len(p.path) < 2:
            lines.append("  found: the start is already within the goal tolerance (a path of "
                         "length 0 m)")
        elif p.success:
            lines.append(f"  found: length {p.length_m:.1f} m, cost {p.cost:.1f}, "
                         f"{p.expansions} expansions, {p.time_s:.2f} s")
            if self.high_cost:
                lines.append(f"  passes high cost (C > {HIGH_COST}) in {len(self.high_cost)} "
                             "stretch(es), starting at:")
                for x, y, th, c in self.high_cost[:8]:
                    lines.append(f"    ({x:.1f}, {y:.1f}) m heading {th:.0f}°: max C = {c:.2f}")
            else:
                lines.append(f"  no cell on the path costs more than {HIGH_COST}")
            if self.route:
                lines.append(f"  route: {self.route}")
        else:
            lines.append(f"  not found: {p.reason} ({p.expansions} expansions, {p.time_s:.2f} s)")
        if self.outcome is not None:
            o = self.outcome
            lines.append(f"  drive: {'success' if o.success else 'failure'} ({o.reason}) after "
                         f"{o.duration_s:.1f} s, {o.goal_distance_m:.1f} m from the goal")
        for label, path in (("figure", self.figure), ("rerun", self.recording)):
            if path is not None:
                lines.append(f"  {label}: {path}")
        if self.not_written:
            lines.append(f"  figure and rerun recording not written: {self.not_written}")
        return "\n".join(lines)

    def as_dict(self) -> dict:
        """The report as plain JSON values (``dgt plan --json``): the query, whether a path
        was found (else why: ``failure``, "no_path" or "budget" as in
        :attr:`PlanResult.failure`, and ``reason`` in words), the path's rows [x m, y m,
        yaw rad], its length [m] and cost, the named route, the drive's outcome (None when
        not driven), the files written and what the costmap read (``input``). Non-finite
        numbers (an unknown goal distance) become None."""
        p = self.plan
        out = {"world": self.world, "vehicle": self.vehicle, "method": self.method,
               "start": list(self.start), "goal": list(self.goal), "found": bool(p.success),
               "failure": None if p.success else p.failure,
               "reason": None if p.success else p.reason,
               "path": np.asarray(p.path, float).reshape(-1, 3).tolist() if p.success else [],
               "length_m": float(p.length_m) if p.success else None,
               "cost": float(p.cost) if p.success else None,
               "expansions": int(p.expansions), "time_s": float(p.time_s),
               "route": self.route, "outcome": None,
               "figure": None if self.figure is None else str(self.figure),
               "recording": None if self.recording is None else str(self.recording),
               "not_written": self.not_written, "never_driven": self.never_driven,
               "input": self.inputs,
               "warnings": list(self.warnings)}
        if self.outcome is not None:
            o = self.outcome
            out["outcome"] = {"success": bool(o.success), "reason": o.reason,
                              "duration_s": _finite(o.duration_s),
                              "goal_distance_m": _finite(o.goal_distance_m)}
        return out


def _finite(value: float) -> float | None:
    """``value`` as a float, or None when it is NaN or infinite (JSON has neither)."""
    return float(value) if math.isfinite(value) else None


def _high_cost_cells(path: np.ndarray, cost: np.ndarray, grid) -> list:
    """Stretches of the path whose cost in the travel direction exceeds HIGH_COST:
    (x, y) where each stretch starts, θ_k [deg] there, and the stretch's highest C."""
    k_layers = cost.shape[0]
    rows, cols = grid.xy_to_cell(path[:, 0], path[:, 1])
    k = nearest_heading_bin(path[:, 2], k_layers) if k_layers > 1 else np.zeros(len(path), int)
    c = cost[k, rows.clip(0, grid.height - 1), cols.clip(0, grid.width - 1)]
    high = c > HIGH_COST
    starts = np.flatnonzero(high & ~np.concatenate([[False], high[:-1]]))
    ends = np.flatnonzero(high & ~np.concatenate([high[1:], [False]]))
    return [(float(path[a, 0]), float(path[a, 1]), 360.0 * int(k[a]) / k_layers,
             float(c[a : b + 1].max())) for a, b in zip(starts, ends, strict=True)]


SLOPE_FIT_RELPATH = "baselines/slope_models.json"
"""The slope-based baseline's fit (``dgt_lib.stages.costmaps.ensure_slope_models``)."""


def _steps_before(what: str, profile: Profile) -> str:
    """The stages that run before ``what`` (e.g. "training the multitask model"): only
    ``what`` when the profile's dataset is cached, else collection and the dataset first."""
    if (data_dir(profile) / DATASET_RELPATH).exists():
        return f"{what} on the cached dataset"
    return (f"collecting the training world's {sum(profile.collect.episodes)} driving episodes "
            f"(those not cached yet), building the dataset, then {what}")


def training_notice(method: str, vehicle: str, profile: Profile) -> str | None:
    """The line announcing which stages run before ``method``'s costmap can be built — a
    model (``dgt``, ``isotropic``, ``single-task``) or the slope fit (``slope``) that the
    profile has not made yet, and the collection and dataset they need when those are not
    cached either — or None when nothing needs to be built first. No time is promised:
    how long the stages take depends on the machine (``dgt reproduce`` prints each one's)."""
    if method in ("dgt", "isotropic", "single-task"):
        kind = "multitask" if method in ("dgt", "isotropic") else f"single:{vehicle}"
        inputs = profile.train.inputs
        relpath, what = model_relpath(kind, inputs), "training it"
        missing = f"trained {'' if inputs == 'rgbd' else inputs + '-only '}{kind} model"
    elif method == "slope":
        relpath, missing, what = SLOPE_FIT_RELPATH, "slope-based fit", "fitting it"
    else:
        return None
    if (data_dir(profile) / relpath).exists():
        return None
    return (f"No {missing} for profile {profile.name!r} yet: {_steps_before(what, profile)}. "
            "Later queries reuse it.")


def check_query(world: World, spec: VehicleSpec, start, goal, profile: Profile | str | None = None,
                *, progress: bool = True) -> None:
    """Raise :class:`~dgt_lib.navigation.planner.InvalidQueryError` for a start or goal
    that cannot be planned, before any dataset or model is built: first from the world
    alone (:func:`~dgt_lib.navigation.planner.check_query_on_world`: writes nothing),
    then on the world's occupancy map, exactly as the planner will check it (needs the
    BEV maps and τ_s — seconds, or the episodes for the training world)."""
    prof = as_profile(profile)
    check_query_on_world(world, spec, start, goal)
    occupancy, grid = world_occupancy(world, prof, progress=progress)
    free = np.zeros((1, *grid.shape), np.float32)  # the costmap plays no part in the check
    HybridAStar.for_vehicle(free, occupancy, grid, spec, prof.planner).check_query(start, goal)


PLAN_SECTIONS: tuple[str, ...] = ("worlds", "collect", "bev", "train", "costmap", "planner",
                                   "experiments")
"""The profile sections a query's plan (and drive) depends on: the data, map and model behind
the costmap, the costmap, the search, the drive's time limit and controller samples."""


def settings_tag(profile: Profile | None) -> str:
    """``""`` for a profile's own settings, else ``"_set-<hash>"`` of the
    :data:`PLAN_SECTIONS` it changes (``--set planner.beta=0``): a query under other
    settings gets its own files and the default query keeps its name. (The profile's
    name and run seed already pick the output directory.)"""
    if profile is None or not profile.overrides:
        return ""
    own = get_profile(profile.name)
    plan = {s: getattr(profile, s) for s in PLAN_SECTIONS}
    if plan == {s: getattr(own, s) for s in PLAN_SECTIONS}:
        return ""
    return "_set-" + artifacts.config_hash(plan)[:8]


def output_stem(world: World, spec: VehicleSpec, method: str, start, goal, *,
                drive: bool = False, profile: Profile | None = None) -> str:
    """File name (no suffix) of a query's figure and recording: readable — world, vehicle,
    method, start x, y [m] and heading [deg], goal x, y [m] — and unique: it ends in a
    hash of the exact query and the world's terrain, so distinct queries (another
    heading, a start 0.3 m away, another heightmap of the same name, driven or not)
    never overwrite each other, and the same query replaces its own files; settings
    changed from the profile's add :func:`settings_tag`. A named vehicle is hashed by its
    name, any other by its spec (two files of one name are two vehicles). The world's and
    vehicle's names
    are cut to :func:`~dgt_lib.core.outputs.bounded_name`'s length, so the name fits any
    file system (the hash tells long names apart)."""
    sx, sy, sth = (float(v) for v in start)
    gx, gy = (float(v) for v in tuple(goal)[:2])
    key = artifacts.config_hash({
        "world": {"name": world.name, "grid": world.grid, "heights": world.heights,
                  "colors": world.colors, "trees": world.trees},
        "vehicle": spec.name if is_named(spec) else spec, "method": method,
        "start": [sx, sy, sth], "goal": [gx, gy], "drive": bool(drive)})[:8]
    heading_deg = float(np.degrees(sth)) % 360.0
    name = bounded_name(spec.name)
    return (f"{bounded_name(world.name)}_{name}_{method}_{sx:.1f}_{sy:.1f}_{heading_deg:.0f}deg_to_"
            f"{gx:.1f}_{gy:.1f}{'_driven' if drive else ''}_{key}{settings_tag(profile)}")


@dataclass
class CostmapSource:
    """The costmap of a vehicle that is not one of the named ones (a vehicle never driven:
    :func:`dgt_lib.app.never_driven.plan_vehicle_query` makes one), for :func:`plan_query`:
    ``maps(world)`` → (the world's maps, cost (K, H, W)); ``notice``, printed before it is
    built; ``described``, the report's line on where it came from; ``warnings`` on the
    spec."""

    maps: Callable[[World], tuple[WorldMaps, np.ndarray]]
    notice: str | None
    described: str
    warnings: list[str] = field(default_factory=list)


def plan_on_world(world: World, spec: VehicleSpec, start, goal, *, method: str = "dgt",
                  profile: Profile | str | None = None, drive: bool = False,
                  out_dir: Path | None = None, progress: bool = True,
                  source: CostmapSource | None = None, inputs: str = "",
                  settings: Profile | None = None) -> QueryReport:
    """Plan (and optionally drive) one query on a loaded ``world``; see the module docstring.

    start (x, y, yaw) [m, m, rad], goal (x, y) [m]. Raises
    :class:`dgt_lib.navigation.planner.InvalidQueryError` when the start or goal is off the map
    or in an obstacle (the message names which) — found before any dataset or model is
    built (:func:`check_query`). With ``progress``, prints when a model must be trained.
    ``profile``: the models that map the world and the planner's settings; driven, the
    vehicle is tracked by its controller (``experiments.controller``) with its seed, as a
    trial is (:func:`drive_query`). ``source``: the costmap of a vehicle that is not a named
    one; ``inputs``: the report's words on what the costmap read; ``settings``: the user's
    settings, which name the output files (:func:`output_stem`; default ``profile``).
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; valid methods: {', '.join(METHODS)}")
    prof = as_profile(profile)
    start = tuple(float(v) for v in start)
    goal = tuple(float(v) for v in goal)[:2]
    check_query(world, spec, start, goal, prof, progress=progress)
    notice = source.notice if source else training_notice(method, spec.name, prof)
    if progress and notice:
        print(notice, flush=True)
    if source:
        maps, cost = source.maps(world)
    else:
        maps = ensure_world_costmaps(world, (spec.name,), prof, methods=(method,),
                                     progress=progress)
        cost = maps.costmap(method, spec.name)
    planner = HybridAStar.for_vehicle(cost, maps.occupancy, maps.grid, spec, prof.planner)
    result = planner.plan(start, goal)
    report = QueryReport(world.name, spec.name, method, start, goal, result, inputs=inputs)
    if source:
        report.never_driven, report.warnings, report.spec = (source.described,
                                                             list(source.warnings), spec)
    if result.success:
        report.high_cost = _high_cost_cells(result.path, cost, maps.grid)
        report.route = classify_route(world, result.path) if world.routes else None
    out_dir = Path(out_dir) if out_dir else data_dir(prof) / "plans"
    stem = output_stem(world, spec, method, start, goal, drive=drive and result.success,
                       profile=prof if settings is None else settings)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        report.figure = _figure(world, maps, cost, report, out_dir / f"{stem}.png")
    except OSError as exc:  # a read-only or full directory: the plan stands without them
        if not is_storage_error(exc):
            raise
        report.not_written = storage_message(exc)
    if drive and result.success:
        report.outcome, traj, speed = drive_query(world, spec, result, goal, maps, cost, prof)
    else:
        traj = speed = None
    if report.not_written is None:
        report.recording = _recording(world, maps, cost, report, traj, speed,
                                      out_dir / f"{stem}.rrd", prof, spec)
    return report


def drive_query(world: World, spec: VehicleSpec, plan: PlanResult, goal, maps: WorldMaps,
                cost: np.ndarray, profile: Profile) -> tuple[TrialOutcome, np.ndarray,
                                                             np.ndarray]:
    """Drive a found ``plan`` as a trial drives it: the profile's controller
    (``experiments.controller``: paper, robust, or terrain reading ``cost``, the costmap
    the plan was made on — :func:`~dgt_lib.evaluation.trials.trial_controller`), its seed
    (``profile.seed``), its MPPI samples and time limit. Returns
    :func:`~dgt_lib.navigation.drive.drive`'s (outcome, trajectory, speed)."""
    from dgt_lib.evaluation.trials import (  # import MPPI: only to drive
        trial_controller,
        trial_time_limit_s,
    )
    from dgt_lib.navigation.drive import drive as drive_path

    limit = trial_time_limit_s(profile.experiments, plan.length_m)
    return drive_path(world, spec, plan.path, goal, occupancy=maps.occupancy,
                      grid=maps.grid, time_limit_s=limit,
                      seed=profile.seed, **trial_controller(profile, cost))


def _figure(world: World, maps, cost, report: QueryReport, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from dgt_lib.viz.planner import plot_query

    fig = plot_query(world, maps, cost, report)
    try:
        artifacts.write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=90, format="png"))
    finally:
        plt.close(fig)
    return path


def _recording(world, maps, cost, report, traj, speed, path: Path, profile: Profile,
               spec: VehicleSpec) -> Path:
    from dgt_lib.viz import recording

    with recording.Recording(path, f"plan_{world.name}", profile) as rec:
        rec.log_terrain(world.heights, world.colors, world.grid)
        rec.log_bev(maps.bev.channels, maps.bev.observed)
        rec.log_occupancy(maps.occupancy)
        rec.log_costmap(cost, maps.grid, report.vehicle, report.method)
        if report.plan.success:
            z = world.height_at(report.plan.path[:, 0], report.plan.path[:, 1]) + 0.5
            rec.log_path(report.method, np.column_stack([report.plan.path[:, :2], z]))
        if traj is not None and len(traj):
            rec.log_trajectory(report.vehicle, traj[:, 0], traj[:, 1:4], {"speed_mps": speed},
                               vehicle=spec)
        rec.log_text("summary", "```\n" + report.summary() + "\n```")
    return path
