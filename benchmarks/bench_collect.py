"""Speed of data collection: episodes per vehicle, the mapping survey, the whole collection.

Run: ``.venv/bin/python benchmarks/bench_collect.py [--profile paper] [--episodes 2]``.

1. Per vehicle, ``--episodes`` episodes of the profile's configuration on its
   training world, in this process (one worker), once with onboard frames and
   once without, so the rendering share is measured: simulated seconds, wall and
   CPU seconds, frames, BEV cells touched, patches, patches per wall-minute.
2. The mapping survey of every world: frames, wall seconds, coverage, median
   |H̄ − h|.
3. ``--pool K``: K episodes per vehicle through ``collect_episodes`` with the
   default process pool (``profile.workers`` processes) in a temporary data
   directory — the real thing, including process start-up. Its throughput
   (simulated seconds per wall second) and the sample's mean episode length per
   vehicle give the estimate of the whole profile's collection:
   Σ_v episodes_v × mean length_v / throughput.

Timings on the shared 2-core machine vary with its load; the load average is printed.
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from dataclasses import replace

import numpy as np

from dgt_lib.core.config import VEHICLES, get_profile
from dgt_lib.perception.bev import BEVAccumulator, bev_grid, bev_quality
from dgt_lib.perception.dataset import patch_times
from dgt_lib.perception.episodes import episode_seed, run_episode
from dgt_lib.perception.locomotion import WINDOW_S
from dgt_lib.stages.collect import build_world_bev as build_bev
from dgt_lib.stages.collect import collect_episodes
from dgt_lib.world.rendering import survey_poses
from dgt_lib.world.terrain import WORLD_NAMES, get_world


def per_vehicle(prof, n_episodes: int) -> None:
    cfg = prof.collect
    world = get_world("training", prof)
    print(f"{'vehicle':13s} {'sim s':>6s} {'wall s':>7s} {'cpu s':>6s} {'render s':>8s} "
          f"{'frames':>6s} {'cells/ep':>8s} {'patches':>7s} {'patch/min':>9s}  end reasons")
    sparse = []
    for v in VEHICLES:
        sim_s = wall = cpu = wall_norender = 0.0
        frames = cells = patches = 0
        reasons = []
        for i in range(n_episodes):
            seed = episode_seed(prof.seed, v, i)
            t0, c0 = time.perf_counter(), time.process_time()
            ep = run_episode(world, v, seed, cfg, index=i)
            t1, c1 = time.perf_counter(), time.process_time()
            run_episode(world, v, seed, cfg, index=i, render=False)
            wall_norender += time.perf_counter() - t1
            wall += t1 - t0
            cpu += c1 - c0
            sim_s += ep.duration_s
            frames += ep.n_frames
            cells += len(ep.bev["cells"])
            sparse.append(ep.bev)
            patches += len(patch_times(ep.time_s, ep.valid, cfg.patch_interval_s,
                                       cfg.patch_start_s, WINDOW_S))
            reasons.append(ep.end_reason)
        print(f"{v:13s} {sim_s:6.0f} {wall:7.1f} {cpu:6.1f} {wall - wall_norender:8.1f} "
              f"{frames:6d} {cells // n_episodes:8d} {patches:7d} {60 * patches / wall:9.0f}  "
              f"{', '.join(reasons)}")
    acc = BEVAccumulator(bev_grid(world.grid.extent))
    t0 = time.perf_counter()
    for s in sparse:
        acc.add_sparse(s)
    dt = time.perf_counter() - t0
    print(f"merging one episode's BEV statistics into the map: {1e3 * dt / len(sparse):.1f} ms")


def survey(prof) -> None:
    print(f"{'world':9s} {'cells':>11s} {'frames':>6s} {'wall s':>7s} {'coverage':>8s} "
          f"{'|H-h| med':>9s}")
    for name in WORLD_NAMES:
        w = get_world(name, prof)
        t0 = time.perf_counter()
        bev, n, _ = build_bev(w, prof.collect)
        dt = time.perf_counter() - t0
        q = bev_quality(bev, w)
        assert n == len(survey_poses(w, prof.collect))
        print(f"{name:9s} {str(w.grid.shape):>11s} {n:6d} {dt:7.1f} {q['coverage']:8.2%} "
              f"{100 * q['height_median_abs_err_m']:7.2f}cm")


def pooled(prof, k: int) -> None:
    sample = prof.with_(collect=replace(prof.collect, episodes=(k,) * len(VEHICLES)))
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["DGT_DATA_DIR"] = tmp
        t0, c0, k0 = time.perf_counter(), time.process_time(), _children_cpu()
        episodes = collect_episodes(sample, progress=False)  # shuts its pool down
        wall = time.perf_counter() - t0
        cpu = time.process_time() - c0 + _children_cpu() - k0
    sim_s = sum(e.duration_s for e in episodes)
    rate = sim_s / wall
    print(f"{len(episodes)} episodes through a pool of {prof.workers} workers: {wall:.1f} s wall "
          f"for {sim_s:.0f} simulated s = {rate:.1f}× real time; {cpu:.0f} CPU s "
          f"({1e3 * cpu / sim_s:.0f} ms per simulated s)")
    expected = 0.0
    for v, n in zip(VEHICLES, prof.collect.episodes, strict=True):
        mean_s = np.mean([e.duration_s for e in episodes if e.vehicle == v])
        expected += n * mean_s
        print(f"  {v:13s} mean episode {mean_s:5.1f} s")
    print(f"estimated collection of '{prof.name}' ({sum(prof.collect.episodes)} episodes, "
          f"~{expected / 3600:.1f} simulated h) with {prof.workers} workers: "
          f"{expected / rate / 60:.0f} min at this load, "
          f"{expected * cpu / sim_s / prof.workers / 60:.0f} min on idle cores (CPU time)")


def _children_cpu() -> float:
    """User + system CPU seconds of this process's reaped child processes."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="demo")
    parser.add_argument("--episodes", type=int, default=2, help="per vehicle, in-process")
    parser.add_argument("--pool", type=int, default=0, help="per vehicle, through the pool")
    parser.add_argument("--skip-survey", action="store_true")
    args = parser.parse_args()
    prof = get_profile(args.profile)
    cfg = prof.collect
    print(f"profile {prof.name}: training world {get_world('training', prof).grid.shape} "
          f"cells, {cfg.episode_duration_s:.0f} s episodes, a frame every "
          f"{cfg.frame_spacing_m} m, a patch every {cfg.patch_interval_s} s; "
          f"load average {os.getloadavg()[0]:.1f}")
    if args.episodes:
        per_vehicle(prof, args.episodes)
    if not args.skip_survey:
        survey(prof)
    if args.pool:
        pooled(prof, args.pool)
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
