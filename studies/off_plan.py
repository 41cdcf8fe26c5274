"""A vehicle pushed off its plan: recorded plans driven from a start beside them, with each
trials' controller — where a terrain-aware controller should matter.

    .venv/bin/python studies/off_plan.py --profile demo --seeds 3 \\
        --experiment experiment1 --experiment experiment2 --offset 2.5 --at 0.4

For every recorded plan of ``--method`` (default DGT-Map) in the cached experiments of run
seeds ``0 … N-1`` (``--seeds N``; or each ``--seed S``), the vehicle starts at rest
``--offset`` metres to the left and to the right of the plan's pose at ``--at`` of its
length, with the plan's heading there, and tracks the rest of the plan to the query's goal
(a start on an occupied cell is skipped, and so is one where the vehicle would stand across
terrain steeper than its static rollover angle, e.g. a cut bank beside a ramp). Each start
is driven with every controller (``experiments.controller``; ``terrain`` reads the method's
costmap) with the trial's seed, batch size and time-limit rule. Printed per controller:
arrivals, immobilized, flipped, and the mean cost of the driven path on the vehicle's DGT-Map
costmap (:func:`dgt_lib.evaluation.driven_cost.driven_cost`), and the paired difference of
the driven cost between controllers on the same starts; then every start that did not arrive
with some controller, with the true terrain's grade and cross-slope under it and where and
when each controller's drive ended.
"""

from __future__ import annotations

import argparse
import multiprocessing
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from runner import Study

from dgt_lib.core import artifacts
from dgt_lib.core.config import get_profile
from dgt_lib.core.controller import CONTROLLERS
from dgt_lib.core.executors import limit_threads
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.evaluation.driven_cost import driven_cost
from dgt_lib.evaluation.statistics import wilson_interval
from dgt_lib.evaluation.trials import method_costmap, trial_controller, trial_time_limit_s
from dgt_lib.navigation.drive import drive
from dgt_lib.stages.experiments import trial_maps
from dgt_lib.stages.paths import data_dir
from dgt_lib.world.terrain import get_world


def pushed_start(path: np.ndarray, at: float, offset_m: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(start pose (x, y, yaw), the rest of the plan from there): the plan's pose at fraction
    ``at`` of its length moved ``offset_m`` to its left (negative: right)."""
    seg = np.hypot(*np.diff(path[:, :2], axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    i = int(np.searchsorted(s, at * s[-1]))
    x, y, yaw = path[i]
    start = np.array([x - offset_m * np.sin(yaw), y + offset_m * np.cos(yaw), yaw])
    return start, path[i:]


def start_grades_deg(world, start: np.ndarray) -> tuple[float, float]:
    """(grade along the start heading, cross-slope to its left) [deg] of the true terrain at a
    start pose (x, y, yaw): uphill ahead and left side high are positive."""
    gx, gy = world.gradient()
    row, col = world.grid.xy_to_cell(start[0], start[1])
    dx, dy = gx[row, col], gy[row, col]
    c, s = np.cos(start[2]), np.sin(start[2])
    return (float(np.degrees(np.arctan(dx * c + dy * s))),
            float(np.degrees(np.arctan(-dx * s + dy * c))))


def footprint_max_slope_deg(world, start: np.ndarray, length_m: float, width_m: float
                            ) -> float:
    """Steepest true-terrain slope [deg] under a vehicle of ``length_m`` × ``width_m`` [m]
    standing at a start pose (x, y, yaw): the cells whose centres lie in its footprint."""
    slope = world.slope_deg()
    res = world.grid.resolution
    reach = int(np.ceil(0.5 * np.hypot(length_m, width_m) / res)) + 1
    row, col = world.grid.xy_to_cell(start[0], start[1])
    h, w = slope.shape
    rows = np.arange(max(row - reach, 0), min(row + reach + 1, h))
    cols = np.arange(max(col - reach, 0), min(col + reach + 1, w))
    xs, ys = world.grid.cell_to_xy(rows[:, None], cols[None, :])
    dx, dy = xs - start[0], ys - start[1]
    c, s = np.cos(start[2]), np.sin(start[2])
    inside = (np.abs(dx * c + dy * s) <= 0.5 * length_m) & (np.abs(-dx * s + dy * c)
                                                            <= 0.5 * width_m)
    return float(slope[np.ix_(rows, cols)][inside].max())


def can_stand(world, vehicle: str, start: np.ndarray) -> bool:
    """Whether the vehicle can be put at rest at a start pose: no terrain under its footprint
    steeper than its static rollover angle, atan(track / 2 / centre-of-mass height). A start
    beside a plan can fall across a cut bank that the start cell alone does not show."""
    spec = get_vehicle(vehicle)
    limit = np.degrees(np.arctan(spec.rollover_accel_mps2 / 9.81))
    return footprint_max_slope_deg(world, start, spec.length_m, spec.width_m) <= limit


def _drive(job: tuple) -> tuple[str, float, float, np.ndarray]:
    """Worker: one pushed start driven with one controller; (reason, driven cost, time it
    ended [s], where it ended (x, y) [m])."""
    profile, world_name, method, vehicle, rest, goal, seed, start, controller = job
    world = get_world(world_name, profile)
    maps = trial_maps(world_name, method, vehicle, profile)
    named = profile.with_overrides({"experiments.controller": controller})
    length_m = float(np.hypot(*np.diff(rest[:, :2], axis=0).T).sum())
    outcome, traj, _ = drive(
        world, vehicle, rest, goal, occupancy=maps.occupancy, grid=maps.grid,
        time_limit_s=trial_time_limit_s(profile.experiments, length_m),
        seed=seed, start_pose=start,
        **trial_controller(named, method_costmap(maps, method, vehicle)))
    dgt = trial_maps(world_name, "dgt", vehicle, profile)
    return (outcome.reason, driven_cost(traj, dgt.costmap("dgt", vehicle), dgt.grid),
            outcome.duration_s, traj[-1, 1:3])


def starts(args: argparse.Namespace, seeds: list[int]) -> list[tuple]:
    """Every pushed start of the recorded plans of run seeds ``seeds``: (experiment, profile,
    world, method, vehicle, rest of the plan, goal, seed, start pose)."""
    out, unstandable = [], Counter()
    for seed in seeds:
        prof = get_profile(args.profile).with_(seed=seed)
        for name in args.experiment:
            path = data_dir(prof) / "experiments" / f"{name}.pkl"
            if not path.exists():
                raise SystemExit(f"no cached {name} for seed {seed} at {path}")
            for r in artifacts.load(path).results:
                if r.task.method != args.method or len(r.path) < 2:
                    continue
                maps = trial_maps(r.task.world, r.task.method, r.task.vehicle, prof)
                for side in (1.0, -1.0):
                    start, rest = pushed_start(np.asarray(r.path, float), args.at,
                                               side * args.offset)
                    row, col = maps.grid.xy_to_cell(start[0], start[1])
                    h, w = maps.occupancy.shape
                    if not (0 <= row < h and 0 <= col < w and maps.occupancy[row, col] == 0):
                        continue
                    if not can_stand(get_world(r.task.world, prof), r.task.vehicle, start):
                        unstandable[name] += 1
                        continue
                    out.append((name, prof, r.task.world, r.task.method, r.task.vehicle,
                                rest, r.task.query.goal, r.task.seed, start))
    for name, k in unstandable.items():
        print(f"  {name}: {k} starts left out, where the vehicle would stand across terrain "
              "steeper than its rollover angle")
    return out


def failures(controllers: list[str], found: list[tuple], out: dict[str, list[tuple]]) -> None:
    """Print every start that did not arrive with some controller: where it started, the true
    terrain's grade and cross-slope there, and how each controller's drive ended."""
    for i, job in enumerate(found):
        if all(out[c][i][0] == "success" for c in controllers):
            continue
        name, prof, world_name, _, vehicle, _, _, _, start = job
        grade, cross = start_grades_deg(get_world(world_name, prof), start)
        ends = "; ".join(f"{c} {out[c][i][0]} at {out[c][i][2]:.1f} s "
                         f"({out[c][i][3][0]:.1f}, {out[c][i][3][1]:.1f})" for c in controllers)
        print(f"  {name} seed {prof.seed} {vehicle} start ({start[0]:.1f}, {start[1]:.1f}) "
              f"heading {np.degrees(start[2]):.0f}°, grade {grade:+.1f}°, cross-slope "
              f"{cross:+.1f}°: {ends}")


def report(controllers: list[str], out: dict[str, list[tuple]]) -> None:
    """Print arrivals, failure reasons and driven cost per controller, then paired costs."""
    for c in controllers:
        rows = out[c]
        k, n = sum(row[0] == "success" for row in rows), len(rows)
        lo, hi = wilson_interval(k, n)
        why = Counter(row[0] for row in rows if row[0] != "success")
        cost = np.nanmean([row[1] for row in rows])
        ended = "".join(f"; {v} {r}" for r, v in why.most_common())
        print(f"  {c:<8} arrived {k}/{n} ({100 * k / n:.0f} %, 95 % {100 * lo:.0f}–"
              f"{100 * hi:.0f}){ended}; mean driven cost {cost:.3f}")
    for a, b in zip(controllers, controllers[1:], strict=False):
        d = np.array([rb[1] - ra[1] for ra, rb in zip(out[a], out[b], strict=True)])
        d = d[np.isfinite(d)]
        print(f"  driven cost {b} − {a}: mean {d.mean():+.3f}, lower on {int((d < 0).sum())}"
              f", higher on {int((d > 0).sum())} of {len(d)} starts")


def main() -> None:
    study = Study("off_plan", __doc__, profile="demo", seeds=3, publishes=False)
    ap = study.parser
    ap.add_argument("--experiment", action="append", default=None,
                    help="cached experiments whose plans to push off (default: 1 and 2)")
    ap.add_argument("--method", default="dgt")
    ap.add_argument("--offset", type=float, default=2.5, help="metres beside the plan")
    ap.add_argument("--at", type=float, default=0.4, help="where along the plan, 0–1")
    ap.add_argument("--controller", action="append", choices=CONTROLLERS, default=None)
    ap.add_argument("--workers", type=int, default=2)
    args = study.parse()
    if not 0.0 <= args.at < 1.0:
        ap.error(f"--at must be in [0, 1), got {args.at}")
    args.experiment = args.experiment or ["experiment1", "experiment2"]
    controllers = args.controller or list(CONTROLLERS)
    found = starts(args, study.seeds)
    experiment_of = [job[0] for job in found]
    jobs = [job[1:] for job in found]
    print(f"{len(jobs)} starts {args.offset} m beside {args.method}'s plans at {args.at:.0%} "
          f"of their length ({', '.join(args.experiment)}; {args.profile} seeds "
          f"{', '.join(map(str, study.seeds))})")
    out = {}
    ctx = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(args.workers, mp_context=ctx, initializer=limit_threads) as pool:
        for c in controllers:
            t0 = time.perf_counter()
            out[c] = list(pool.map(_drive, [(*job, c) for job in jobs]))
            print(f"  [{c}: {time.perf_counter() - t0:.0f} s]", flush=True)
    for name in args.experiment:
        mine = [i for i, e in enumerate(experiment_of) if e == name]
        print(f"{name} ({len(mine)} starts):")
        report(controllers, {c: [rows[i] for i in mine] for c, rows in out.items()})
    print("all:")
    report(controllers, out)
    if any(reason != "success" for rows in out.values() for reason, *_ in rows):
        print("starts that did not arrive with some controller:")
        failures(controllers, found, out)


if __name__ == "__main__":
    main()
