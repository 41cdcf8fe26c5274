"""Closed-loop trials: where their time goes, and MPPI's two backends on recorded trials.

Run after a finished run of the profile (its experiments are read from the cache)::

    .venv/bin/python benchmarks/bench_trials.py --profile paper --seed 0 --every 40

Reruns every ``--every``-th recorded trial of each experiment in this process, one
thread, with MPPI's ``compiled`` backend (the default) and its ``numpy`` reference, and
prints wall seconds per simulated second, the share of ``MPPIController.compute`` in it,
and whether each rerun gives the recorded trial again (plan, trajectory, outcome: the
simulator is deterministic on one machine, so it should on the machine that recorded it).
``--publish`` writes the table's record (``benchmarks/publish.py``) for docs/speed.md.
"""

from __future__ import annotations

import argparse
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one core, as each trial worker
os.environ.setdefault("MUJOCO_GL", "egl")

import time  # noqa: E402

import numpy as np  # noqa: E402
from publish import Benchmark  # noqa: E402

import dgt_lib.navigation.drive as drive_module  # noqa: E402
from dgt_lib.core.config import get_profile  # noqa: E402
from dgt_lib.evaluation.experiments import EXPERIMENTS  # noqa: E402
from dgt_lib.evaluation.trials import TrialResult, _planner, run_trial  # noqa: E402
from dgt_lib.navigation.control.mppi import BACKENDS, MPPIController  # noqa: E402
from dgt_lib.records.study import table  # noqa: E402
from dgt_lib.stages.experiments import (  # noqa: E402
    ensure_experiment,
    experiment_path,
    reproduce_command,
    trial_maps,
)


class TimedMPPI(MPPIController):
    """MPPIController with a chosen backend that adds up the seconds spent in compute()."""

    backend_choice = "compiled"
    seconds = 0.0

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **{**kwargs, "backend": TimedMPPI.backend_choice})

    def compute(self, *args, **kwargs):
        t0 = time.perf_counter()
        try:
            return super().compute(*args, **kwargs)
        finally:
            TimedMPPI.seconds += time.perf_counter() - t0


def same_trial(a: TrialResult, b: TrialResult) -> bool:
    return (a.outcome == b.outcome and np.array_equal(a.path, b.path)
            and np.array_equal(a.trajectory, b.trajectory))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--profile", default="demo")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--every", type=int, default=20, help="rerun every n-th recorded trial")
    bench = Benchmark("bench_trials", ap)
    args = ap.parse_args()
    prof = get_profile(args.profile).with_(seed=args.seed)
    drive_module.MPPIController = TimedMPPI
    recorded: list[TrialResult] = []
    for name in EXPERIMENTS:
        if not experiment_path(name, prof).exists():
            raise SystemExit(f"{name} of {args.profile} seed {args.seed} is not cached: run "
                             f"`{reproduce_command(prof)}` first")
        recorded += ensure_experiment(name, prof, progress=False).results[::args.every]
    for t in {(r.task.world, r.task.method, r.task.vehicle, r.task.profile) for r in recorded}:
        _planner(*t, trial_maps)  # every costmap and planner loaded outside the timing
    run_trial(recorded[0].task, trial_maps)  # and the compiled code
    print(f"{args.profile} seed {args.seed}: {len(recorded)} recorded trials (every "
          f"{args.every}-th), one thread")
    wall, rows = {}, []
    for backend in BACKENDS:
        TimedMPPI.backend_choice, TimedMPPI.seconds = backend, 0.0
        simulated, same, t0 = 0.0, 0, time.perf_counter()
        for old in recorded:
            new = run_trial(old.task, trial_maps)
            simulated += new.trajectory[-1, 0] if len(new.trajectory) else 0.0
            same += same_trial(new, old)
        wall[backend] = time.perf_counter() - t0
        rows.append([f"`{backend}`", f"{wall[backend]:.1f} s", f"{simulated:.0f} s",
                     f"{wall[backend] / simulated:.3f} s",
                     f"{100 * TimedMPPI.seconds / wall[backend]:.0f} %",
                     f"{same}/{len(recorded)}"])
        print(" | ".join(rows[-1]), flush=True)
    rows[0][0] += f" (**{wall['numpy'] / wall['compiled']:.2f}×** faster)"
    bench.finish({"trials": table(
        f"{len(recorded)} recorded trials of seed {args.seed} (every {args.every}-th of each "
        "experiment) rerun in one thread with each MPPI backend",
        ["MPPI backend", "wall", "simulated", "wall per simulated second", "in MPPI",
         "trials as recorded"], rows)}, args.publish, profile=args.profile)

if __name__ == "__main__":
    main()
