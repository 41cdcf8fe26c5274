"""The same collection episodes and closed-loop trials through each executor: wall time and
whether the results are identical (docs/scale-out.md).

Run: ``.venv/bin/python benchmarks/bench_executors.py [--profile smoke] [--workers 2]
[--executors process dask] [--episodes N] [--trials 4]``.

1. The profile's collection episodes (smoke: 3 per vehicle, 20 s each; ``--episodes N``:
   N per vehicle) through
   ``collect_episodes`` in a fresh temporary data directory per executor — the real
   thing: for Dask a local cluster of ``--workers`` single-threaded workers is
   started for the call and stopped after, and that start-up is in the wall time (also
   printed on its own).
2. ``--trials`` closed-loop trials of Experiment 1 (carla_cola on the hill, the binary
   costmap, which needs no model) through ``run_trials``, on costmaps built once
   beforehand; every executor reads the same cache.

Every executor's episodes (all stored arrays, BEV statistics included) and trial results
(outcome, plan, trajectory) are compared with the process pool's. Timings on the shared
2-core machine vary with its load; the load average is printed, and ``--publish`` writes the
table's record (``benchmarks/publish.py``) with it for docs/scale-out.md.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from publish import Benchmark

from dgt_lib.core import artifacts
from dgt_lib.core.config import EXECUTORS, ExecutionConfig, get_profile
from dgt_lib.core.executors import make_executor, run_jobs, use_executor
from dgt_lib.evaluation.queries import hill_queries
from dgt_lib.evaluation.trials import run_trials, trial_tasks
from dgt_lib.perception.episodes import load_episode
from dgt_lib.records.study import table
from dgt_lib.stages.collect import collect_episodes
from dgt_lib.stages.experiments import trial_maps
from dgt_lib.stages.paths import data_dir
from dgt_lib.world.terrain import get_world

PACKAGES = {"dask": "distributed"}
EXECUTOR_NAMES = {"process": "process pool (default)",
                  "dask": "Dask `LocalCluster`, {workers} workers"}


def _noop(i: int) -> int:
    return i


def startup_s(kind: str, workers: int) -> float:
    """Open the executor, run one trivial job per worker, close it."""
    t0 = time.perf_counter()
    with make_executor(kind, workers=workers) as ex:
        run_jobs(_noop, [(i,) for i in range(workers)], executor=ex, progress=False)
    return time.perf_counter() - t0


def stored_episodes(prof) -> dict[str, dict[str, np.ndarray]]:
    root = data_dir(prof)
    return {p.name: load_episode(p, with_bev=True).to_arrays()
            for p in sorted((root / "episodes").glob("*.npz"))}


def same_arrays(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(
        x.keys() == y.keys() and all(np.array_equal(x[k], y[k]) for k in x)
        for x, y in ((a[n], b[n]) for n in a))


def same_trials(a, b) -> bool:
    return all(x.task == y.task and x.outcome == y.outcome and x.route == y.route
               and np.array_equal(x.path, y.path) and np.array_equal(x.trajectory, y.trajectory)
               for x, y in zip(a, b, strict=True))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="smoke")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--executors", nargs="+", default=["process", "dask"], choices=EXECUTORS)
    parser.add_argument("--episodes", type=int, default=None, metavar="N",
                        help="episodes per vehicle (default: the profile's)")
    parser.add_argument("--trials", type=int, default=4)
    bench = Benchmark("bench_executors", parser)
    args = parser.parse_args()
    kinds = [k for k in args.executors
             if k == "process" or importlib.util.find_spec(PACKAGES[k]) is not None]
    for k in sorted(set(args.executors) - set(kinds)):
        print(f"{k}: not installed (pip install 'dgt-kit[{k}]'), skipped")
    prof = get_profile(args.profile).with_(workers=args.workers)
    if args.episodes is not None:
        prof = prof.with_(collect=replace(prof.collect, episodes=(args.episodes,) * 4))
    n_eps = sum(prof.collect.episodes)
    print(f"profile {prof.name}, {args.workers} workers; {n_eps} episodes of "
          f"{prof.collect.episode_duration_s:.0f} s, {args.trials} trials")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        ref_eps = ref_trials = None
        maps_dir = Path(tmp) / "maps"
        os.environ[artifacts.DATA_ENV_VAR] = str(maps_dir)
        queries = hill_queries(get_world("hill", prof), args.trials, prof.experiments, prof.seed)
        tasks = trial_tasks("experiment1", "hill", "carla_cola", queries, ["binary"], prof)
        trial_maps("hill", "binary", "carla_cola", prof)
        for kind in kinds:
            start = startup_s(kind, args.workers) if kind != "process" else None
            os.environ[artifacts.DATA_ENV_VAR] = str(Path(tmp) / kind)
            run = prof.with_(execution=ExecutionConfig(kind))
            t0 = time.perf_counter()
            collect_episodes(run, progress=False)
            eps_s = time.perf_counter() - t0
            episodes = stored_episodes(run)
            os.environ[artifacts.DATA_ENV_VAR] = str(maps_dir)
            t0 = time.perf_counter()
            with use_executor(kind, workers=args.workers):
                results = run_trials(tasks, trial_maps, workers=args.workers, progress=False)
            trials_s = time.perf_counter() - t0
            if ref_eps is None:
                ref_eps, ref_trials, same = episodes, results, "reference"
            else:
                same = ("identical (every stored array, every trial)"
                        if same_arrays(ref_eps, episodes) and same_trials(ref_trials, results)
                        else "**different**")
            rows.append([EXECUTOR_NAMES[kind].format(workers=args.workers),
                         "—" if start is None else f"{start:.1f} s", f"{eps_s:.1f} s",
                         f"{trials_s:.1f} s", same])
            print(" | ".join(rows[-1]), flush=True)
    bench.finish({"executors": table(
        f"`{prof.name}`: {n_eps} collection episodes of {prof.collect.episode_duration_s:.0f} s "
        f"and {args.trials} trials of Experiment 1 (carla_cola, Binary) on {args.workers} "
        "workers, each call starting and stopping its executor",
        ["executor", "start-up", f"{n_eps} episodes", f"{args.trials} trials",
         "results against the process pool"], rows)}, args.publish, profile=prof.name)

if __name__ == "__main__":
    main()
