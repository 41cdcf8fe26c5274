"""Replay one recorded closed-loop trial and print what MPPI commanded, state by state.

    .venv/bin/python studies/replay_trial.py --profile demo --seed 6 \\
        --experiment experiment1 --method dgt --label ascent --index 0 --from-s 14

A trial of a cached experiment (``data/<profile>/seed-<S>/experiments/<name>.pkl``) is
driven again from its stored plan with :func:`dgt_lib.navigation.drive.drive`, the way
:func:`dgt_lib.evaluation.trials.run_trial` drove it (same occupancy map, time limit, MPPI
batch and seed), so on the machine that recorded it the replay ends where the trial ended
(the script checks it and says so). Every ``--every-s`` seconds from ``--from-s`` it tables
the pose, the height of the chassis origin above the terrain, pitch and roll, the speed,
MPPI's speed command and steering (a fraction of the lock, + left), the wheels in contact
and how long the vehicle has been immobile: what a person wants to see to tell a physical
limit (a wheel off the ground, a roll past the tipping angle) from a controller's choice (a
crawl commanded, full lock at full speed). ``--controller NAME`` replays the experiment
recorded with ``experiments.controller=NAME``. ``--mppi FIELD=VALUE[,…]`` drives the same plan
with other MPPI settings (``controller_variants.py`` names the trials they change).
``--critics`` adds what MPPI's last call saw among its sampled sequences: the share whose
footprint collides with the occupancy map (cost ≥ ``collision_weight``), the same share among
the fast ones (mean speed over the horizon ≥ ``--fast-mps``), the mean speed of the cheapest
sequence, and how much more the cheapest fast one costs (∞: every fast one collides) — to
tell a crawl chosen because every fast sequence collides from one chosen for other critics.
Watching changes nothing: the sequences, costs and commands are those of the trial.
``--publish`` writes the table to a record that a docs page quotes.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import replace

import numpy as np
from runner import Study

from dgt_lib.core.config import get_profile
from dgt_lib.core.controller import CONTROLLERS
from dgt_lib.evaluation.trials import method_costmap, trial_controller, trial_time_limit_s
from dgt_lib.navigation.control.mppi import MPPIController
from dgt_lib.navigation.control.mppi_config import parse_mppi_settings
from dgt_lib.navigation.drive import drive
from dgt_lib.records.study import table
from dgt_lib.stages.experiments import (
    experiment_path,
    reproduce_command,
    stored_experiment,
    trial_maps,
)
from dgt_lib.world.simulator import VehicleState
from dgt_lib.world.terrain import get_world


def mppi_settings(text: str) -> dict[str, object]:
    """``--mppi``'s value as MPPIConfig fields (argparse reports a bad one)."""
    try:
        return parse_mppi_settings(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


@contextmanager
def watching_sampled_costs(fast_mps: float) -> Iterator[Callable[[], list[str]]]:
    """Within the block, MPPI's sampled-cost step (compiled backend) keeps statistics of
    each call's sampled sequences; yields a function that gives the latest call's cells (share
    colliding [%], share of the fast ones colliding [%], the cheapest sequence's mean speed
    [m/s], the cheapest collision-free fast one's extra cost). The wrapper returns what it
    was given, so the trial is unchanged; the method is restored on leaving."""
    original = MPPIController._sampled_costs_compiled
    last: dict[str, float] = {}

    def wrapped(self, *args, **kwargs):
        v, w, cost = original(self, *args, **kwargs)
        mean_v = v.mean(axis=0)  # (B,) commanded speed over the horizon [m/s]
        hit = cost >= self.cfg.collision_weight
        fast = mean_v >= fast_mps
        best = int(np.argmin(cost))
        last.update(collide=float(hit.mean()),
                    fast_collide=float(hit[fast].mean()) if fast.any() else math.nan,
                    best_v=float(mean_v[best]),
                    fast_extra=(float(cost[fast & ~hit].min() - cost[best])
                                if (fast & ~hit).any() else math.inf))
        return v, w, cost

    def latest() -> list[str]:
        if not last:
            return ["", "", "", ""]
        return [f"{100 * last['collide']:.1f}", f"{100 * last['fast_collide']:.1f}",
                f"{last['best_v']:.2f}", f"{last['fast_extra']:.2f}"]

    MPPIController._sampled_costs_compiled = wrapped
    try:
        yield latest
    finally:
        MPPIController._sampled_costs_compiled = original


def main() -> None:
    study = Study("replay_trial", __doc__, profile="demo", seeds=1)
    ap = study.parser
    ap.add_argument("--experiment", default="experiment1")
    ap.add_argument("--method", default="dgt")
    ap.add_argument("--label", default=None, help="query label, e.g. ascent (default: any)")
    ap.add_argument("--vehicle", default=None, help="default: any")
    ap.add_argument("--index", type=int, default=0,
                    help="which of the matching trials, in the recorded order")
    ap.add_argument("--from-s", type=float, default=0.0, help="table from this time [s]")
    ap.add_argument("--every-s", type=float, default=0.5, help="table interval [s]")
    ap.add_argument("--mppi", default=None, type=mppi_settings, metavar="FIELD=VALUE[,…]",
                    help="drive with these MPPIConfig settings instead of the recorded ones")
    ap.add_argument("--controller", choices=CONTROLLERS, default="paper",
                    help="the trials' controller (experiments.controller) whose recorded "
                         "experiment to replay, driven with it")
    ap.add_argument("--hazard", action="store_true",
                    help="the experiment run with experiments.eval_hazard_world=true")
    ap.add_argument("--critics", action="store_true",
                    help="also table what MPPI's sampled sequences cost (see above)")
    ap.add_argument("--fast-mps", type=float, default=1.5,
                    help="--critics: a sequence is fast from this mean speed [m/s]")
    args = study.parse()
    if len(study.seeds) != 1:
        ap.error("one trial is replayed: give the run seed of its experiment as --seed S")
    seed = study.seeds[0]

    overrides: dict[str, object] = {"experiments.controller": args.controller}
    if args.hazard:
        overrides["experiments.eval_hazard_world"] = True
    prof = get_profile(args.profile).with_(seed=seed).with_overrides(overrides)
    path = experiment_path(args.experiment, prof)
    result = stored_experiment(args.experiment, prof)
    if result is None:
        raise SystemExit(f"no cached {args.experiment} at {path}: run "
                         f"`{reproduce_command(prof)}` first")
    trials = [r for r in result.results if r.task.method == args.method
              and (args.label is None or r.task.query.label == args.label)
              and (args.vehicle is None or r.task.vehicle == args.vehicle)]
    if not trials:
        raise SystemExit(f"no {args.method} trial with label {args.label!r} in {path}")
    if not 0 <= args.index < len(trials):
        raise SystemExit(f"--index must be in 0..{len(trials) - 1}")
    rec = trials[args.index]
    task = rec.task
    title = (f"{args.experiment} seed {seed}, {args.controller} controller: {task.method} "
             f"{task.vehicle} {task.query.label} #{args.index} (route {rec.route or '-'}), "
             f"recorded: {rec.outcome.reason} after {rec.outcome.duration_s:.1f} s at "
             f"({rec.trajectory[-1, 1]:.1f}, {rec.trajectory[-1, 2]:.1f}) m")
    print(title)
    if len(rec.path) == 0:
        raise SystemExit("the trial has no plan to drive")
    world = get_world(task.world, prof)
    maps = trial_maps(task.world, task.method, task.vehicle, prof)
    control = trial_controller(prof, method_costmap(maps, task.method, task.vehicle))
    if args.mppi:
        control["mppi"] = replace(control["mppi"], **args.mppi)
    length_m = float(np.hypot(*np.diff(rec.path[:, :2], axis=0).T).sum())
    next_row, rows = [args.from_s], []
    watching = (watching_sampled_costs(args.fast_mps) if args.critics
                else nullcontext(lambda: []))

    def show(state: VehicleState, speed_cmd: float, steer: float) -> None:
        if state.time_s + 1e-9 < next_row[0]:
            return
        next_row[0] += args.every_s
        x, y, z = state.position
        deg = math.degrees
        rows.append([f"{state.time_s:.2f}", f"{x:.1f}", f"{y:.1f}",
                     f"{z - world.height_at(x, y):.2f}", f"{deg(state.yaw):.0f}",
                     f"{deg(state.pitch):.1f}", f"{deg(state.roll):.1f}",
                     f"{state.speed_mps:.2f}", f"{speed_cmd:.2f}", f"{steer:+.2f}",
                     "".join(str(int(c)) for c in state.wheel_contacts),
                     str(int(state.chassis_contact)), f"{state.immobilized_s:.1f}", *critics()])

    with watching as critics:
        outcome, traj, _ = drive(world, task.vehicle, rec.path, task.query.goal,
                                 occupancy=maps.occupancy, grid=maps.grid,
                                 time_limit_s=trial_time_limit_s(prof.experiments, length_m),
                                 seed=task.seed, on_command=show, **control)
    same = (outcome.reason == rec.outcome.reason
            and np.allclose(traj[-1, 1:3], rec.trajectory[-1, 1:3], atol=0.05))
    verdict = ("as recorded" if same else "otherwise than recorded" if args.mppi
               else "NOT as recorded (another machine or code?)")
    ending = (f"replay{' with ' + str(args.mppi) if args.mppi else ''}: {outcome.reason} after "
              f"{outcome.duration_s:.1f} s at ({traj[-1, 1]:.1f}, {traj[-1, 2]:.1f}) m — {verdict}")
    columns = ["t [s]", "x [m]", "y [m]", "chassis above terrain [m]", "yaw [°]",
               "pitch [°, + nose up]", "roll [°, + left up]", "v [m/s]", "v_cmd [m/s]",
               "steer [of the lock, + left]", "wheels touching (fl fr rl rr)", "chassis touching",
               "immobile [s]"]
    if args.critics:
        columns += ["sequences colliding [%]", f"those ≥ {args.fast_mps:g} m/s colliding [%]",
                    "cheapest's mean v [m/s]", "cheapest collision-free fast one: extra cost"]
    study.finish({"replay": table(title, columns, rows)}, lists={"ending": [ending]},
                 seeds=[seed],
                 variant=f"{args.experiment}-{task.query.label}{args.index}-{args.controller}")

if __name__ == "__main__":
    main()
