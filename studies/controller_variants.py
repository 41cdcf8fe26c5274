"""Recorded closed-loop trials driven again with other MPPI settings: what the controller
changes, with the plans held fixed.

    .venv/bin/python studies/controller_variants.py --profile demo --seeds 8 \\
        --experiment experiment1 --route A \\
        --variant lateral_accel_max=2.0 --variant constraint_weight=20

Every trial of the cached experiments of run seeds ``0 … N-1`` (``--seeds N``; or each
``--seed S``) that matches the filters (``--route``, ``--label``, ``--method``) is driven
again from its recorded plan — the plan does not depend on the controller — once per
``--variant`` (``FIELD=VALUE[,FIELD=VALUE]`` of
:class:`dgt_lib.navigation.control.mppi_config.MPPIConfig`; several fields in one variant
are changed together), with the trial's own seed, time limit and occupancy map, in a pool
of ``--workers`` processes; ``--controller NAME`` adds a variant driven as the trials drive
with ``experiments.controller=NAME`` (``terrain``: MPPI reads the method's own costmap).
It prints, per variant and query label, how many arrived and how the others ended, beside
the recorded outcomes, and which trials ended otherwise than recorded (named as
``replay_trial.py --mppi`` replays them); ``--check`` also drives the defaults again (none
should end otherwise on the machine that recorded them).
An exploration tool: the experiments keep the default settings.
"""

from __future__ import annotations

import argparse
import collections
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import numpy as np
from runner import Study

from dgt_lib.core import artifacts
from dgt_lib.core.config import get_profile
from dgt_lib.core.controller import CONTROLLERS
from dgt_lib.core.executors import limit_threads
from dgt_lib.evaluation.trials import method_costmap, trial_controller, trial_time_limit_s
from dgt_lib.navigation.control.mppi_config import parse_mppi_settings
from dgt_lib.navigation.drive import drive
from dgt_lib.stages.experiments import trial_maps
from dgt_lib.stages.paths import data_dir
from dgt_lib.world.terrain import get_world


def parse_variant(text: str) -> dict[str, object]:
    """``--variant``'s value as MPPIConfig fields (argparse reports a bad one)."""
    try:
        return parse_mppi_settings(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _drive(job: tuple) -> tuple[str, bool, float]:
    """Worker: drive one recorded plan with one variant, MPPI fields or a controller's name;
    (reason, success, duration [s])."""
    profile, world_name, method, vehicle, path, goal, seed, variant = job
    world = get_world(world_name, profile)
    maps = trial_maps(world_name, method, vehicle, profile)
    if isinstance(variant, str):
        named = profile.with_overrides({"experiments.controller": variant})
        control = trial_controller(named, method_costmap(maps, method, vehicle))
    else:
        control = {"mppi": replace(profile.mppi, **variant)}
    length_m = float(np.hypot(*np.diff(path[:, :2], axis=0).T).sum())
    outcome, _, _ = drive(world, vehicle, path, goal, occupancy=maps.occupancy, grid=maps.grid,
                          time_limit_s=trial_time_limit_s(profile.experiments, length_m),
                          seed=seed, **control)
    return outcome.reason, outcome.success, outcome.duration_s


def summary(rows: list[tuple[str, str, bool, float]]) -> str:
    """'label: k/n arrived (reasons), mean arrival time' per query label."""
    parts = []
    for label in sorted({r[0] for r in rows}):
        mine = [r for r in rows if r[0] == label]
        k = sum(r[2] for r in mine)
        reasons = collections.Counter(r[1] for r in mine if not r[2])
        times = [r[3] for r in mine if r[2]]
        why = ", ".join(f"{n} {reason}" for reason, n in reasons.most_common())
        mean_t = f", arrivals {np.mean(times):.1f} s" if times else ""
        parts.append(f"{label} {k}/{len(mine)}" + (f" ({why})" if why else "") + mean_t)
    return "; ".join(parts)


def main() -> None:
    study = Study("controller_variants", __doc__, profile="demo", seeds=3, publishes=False)
    ap = study.parser
    ap.add_argument("--experiment", default="experiment1")
    ap.add_argument("--route", default=None, help="only plans of this route, e.g. A")
    ap.add_argument("--label", default=None, help="only these queries, e.g. ascent")
    ap.add_argument("--method", default=None, help="only this method, e.g. dgt")
    ap.add_argument("--variant", action="append", default=[], type=parse_variant,
                    help="FIELD=VALUE[,FIELD=VALUE] of MPPIConfig (repeatable)")
    ap.add_argument("--controller", action="append", default=[], choices=CONTROLLERS,
                    help="a trials' controller by name (experiments.controller; repeatable)")
    ap.add_argument("--check", action="store_true", help="also drive the defaults again")
    ap.add_argument("--workers", type=int, default=2)
    args = study.parse()

    trials, names, profs = [], [], []  # names: as replay_trial.py's --seed/--method/--label/--index
    seeds = study.seeds
    for seed in seeds:
        prof = get_profile(args.profile).with_(seed=seed)
        path = data_dir(prof) / "experiments" / f"{args.experiment}.pkl"
        if not path.exists():
            raise SystemExit(f"no cached {args.experiment} for seed {seed} at {path}")
        index: collections.Counter = collections.Counter()
        for r in artifacts.load(path).results:
            key = (r.task.method, r.task.query.label)
            if (len(r.path) > 1 and (args.route is None or r.route == args.route)
                    and (args.label is None or r.task.query.label == args.label)
                    and (args.method is None or r.task.method == args.method)):
                trials.append(r)
                profs.append(prof)  # the run's profile (a pickled task's may be older code's)
                names.append(f"seed {seed} {key[0]} {key[1]} #{index[key]}")
            index[key] += 1
    if not trials:
        raise SystemExit("no recorded trial matches the filters")
    recorded = [(r.task.query.label, r.outcome.reason, r.outcome.success,
                 r.outcome.duration_s) for r in trials]
    print(f"{len(trials)} recorded trials of {args.experiment} ({args.profile}, seeds "
          f"{', '.join(map(str, seeds))}, route {args.route or 'any'}, "
          f"label {args.label or 'any'}, method {args.method or 'any'})")
    print(f"  recorded: {summary(recorded)}")
    variants = ([{}] if args.check else []) + args.variant + args.controller
    ctx = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(args.workers, mp_context=ctx, initializer=limit_threads) as pool:
        for settings in variants:
            t0 = time.perf_counter()
            jobs = [(prof, r.task.world, r.task.method, r.task.vehicle, r.path,
                     r.task.query.goal, r.task.seed, settings)
                    for r, prof in zip(trials, profs, strict=True)]
            out = list(pool.map(_drive, jobs))
            rows = [(r.task.query.label, *o) for r, o in zip(trials, out, strict=True)]
            name = (f"controller {settings}" if isinstance(settings, str) else
                    ", ".join(f"{k}={v}" for k, v in settings.items()) or "defaults again")
            print(f"  {name}: {summary(rows)}  [{time.perf_counter() - t0:.0f} s]")
            changed = [(who, r.outcome.reason, o[0])
                       for who, r, o in zip(names, trials, out, strict=True)
                       if o[0] != r.outcome.reason]
            print(f"    {len(changed)} of {len(trials)} ended otherwise than recorded"
                  + ("" if not changed or len(changed) > 12 else ": " + "; ".join(
                      f"{who} {was} → {now}" for who, was, now in changed)))


if __name__ == "__main__":
    main()
