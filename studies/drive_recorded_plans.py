"""Recorded plans of another run driven on this profile's maps, with each named controller.

    .venv/bin/python studies/drive_recorded_plans.py RESULTS.pkl --profile smoke \\
        --index 0 --index 22 --controller paper --controller robust

``RESULTS.pkl`` is a cached experiment (``data/<profile>/seed-<S>/experiments/<name>.pkl``,
read only). Each chosen trial's plan is driven in MuJoCo from its first pose with the
trial's seed, MPPI batch size and time limit, as :func:`dgt_lib.evaluation.trials.run_trial`
drives it, but on the world and
occupancy map of ``--profile`` and with the controller of ``experiments.controller=NAME``
(``terrain``: MPPI reads the method's costmap of ``--profile``). The hill and the ridge are
the same in every profile, so a plan recorded on a larger profile can be driven on smoke's
maps without building that profile; where those maps equal the recording's, ``paper``
ends as recorded (the script prints both). Prints how each drive ended.
"""

from __future__ import annotations

import time

import numpy as np
from runner import Study

from dgt_lib.core import artifacts
from dgt_lib.core.config import get_profile
from dgt_lib.core.controller import CONTROLLERS
from dgt_lib.evaluation.trials import method_costmap, trial_controller, trial_time_limit_s
from dgt_lib.navigation.drive import drive
from dgt_lib.stages.experiments import trial_maps
from dgt_lib.world.terrain import get_world


def main() -> None:
    study = Study("drive_recorded_plans", __doc__, profile="smoke", per_seed=False,
                  publishes=False)
    ap = study.parser
    ap.add_argument("results", help="a cached experiment's .pkl (read only)")
    ap.add_argument("--index", type=int, action="append", required=True,
                    help="trial index in the results (repeatable)")
    ap.add_argument("--controller", action="append", choices=CONTROLLERS, default=None,
                    help="experiments.controller values to drive with (default: all)")
    args = study.parse()
    results = artifacts.load(args.results).results
    for i in args.index:
        rec, task = results[i], results[i].task
        prof = get_profile(args.profile)
        world = get_world(task.world, prof)
        maps = trial_maps(task.world, task.method, task.vehicle, prof)
        cost = method_costmap(maps, task.method, task.vehicle)
        recorded = task.profile.experiments  # the trial's time limit
        length_m = float(np.hypot(*np.diff(rec.path[:, :2], axis=0).T).sum())
        end = rec.trajectory[-1, 1:3]
        print(f"#{i} {task.method} {task.vehicle} {task.query.label} (route {rec.route}): "
              f"recorded {rec.outcome.reason} after {rec.outcome.duration_s:.1f} s at "
              f"({end[0]:.1f}, {end[1]:.1f}) m")
        for name in args.controller or CONTROLLERS:
            t0 = time.perf_counter()
            # the trial's own MPPI samples, with the named preset
            named = task.profile.with_overrides({"experiments.controller": name})
            outcome, traj, _ = drive(
                world, task.vehicle, rec.path, task.query.goal, occupancy=maps.occupancy,
                grid=maps.grid, time_limit_s=trial_time_limit_s(recorded, length_m),
                seed=task.seed,
                **trial_controller(named, cost))
            print(f"    {name:<7} {outcome.reason} after {outcome.duration_s:.1f} s at "
                  f"({traj[-1, 1]:.1f}, {traj[-1, 2]:.1f}) m  [{time.perf_counter() - t0:.0f} s]")


if __name__ == "__main__":
    main()
