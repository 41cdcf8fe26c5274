"""How often does a collection run drive down steep ground? Four collection variants:

    .venv/bin/python studies/descent_coverage.py --profile demo --vehicle carla_cola --runs 20

Each variant drives the profile's first ``--runs`` episodes of the vehicle (seed 0's episode
seeds) on the training world without rendering, samples every run like the dataset does
(one sample per ``patch_interval_s`` from ``patch_start_s``) and measures the terrain's
grade along the heading there (true heights, ±2 m). Variants:

- ``paper``: the paper's runs, ending at the first stall (the default);
- ``turn-around``: ``CollectConfig.turn_around_after_stall``;
- ``turn-around + height-uniform spawns``: spawn poses redrawn until their height is
  uniformly distributed over the world's height range (rejection sampling);
- ``downhill spawns``: spawns allowed on slopes up to 30°, facing down the slope ± 45° where
  it is steeper than 15°.

It prints the driving time and how many samples climb or descend beyond 10/15/21°: the
data a head needs to learn that its vehicle descends what it cannot climb (README, Results).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np

from dgt_lib.core.config import get_profile
from dgt_lib.perception.episodes import episode_seed, run_episode, spawn_pose
from dgt_lib.world.terrain import get_world


def heading_grades_deg(world, ep, interval_s: float, start_s: float) -> np.ndarray:
    """Grade [deg] of the true terrain along the heading (±2 m) at the dataset's sample times."""
    t = np.arange(start_s, ep.time_s[-1], interval_s)
    x = np.interp(t, ep.time_s, ep.pose[:, 0])
    y = np.interp(t, ep.time_s, ep.pose[:, 1])
    yaw = np.interp(t, ep.time_s, np.unwrap(ep.pose[:, 2]))
    ahead = world.height_at(x + 2 * np.cos(yaw), y + 2 * np.sin(yaw))
    behind = world.height_at(x - 2 * np.cos(yaw), y - 2 * np.sin(yaw))
    return np.degrees(np.arctan((ahead - behind) / 4.0))


def height_uniform_spawn(world, vehicle, rng, cfg) -> np.ndarray:
    """A free spawn pose whose height is uniform over the world's heights (rejection)."""
    hist, edges = np.histogram(world.heights, bins=20)
    density = hist / hist.sum()
    floor = density[density > 0].min()
    while True:
        pose = spawn_pose(world, vehicle, rng, cfg)
        b = int(np.clip(np.searchsorted(edges, world.height_at(pose[0], pose[1])) - 1, 0, 19))
        if rng.uniform() < floor / density[b]:
            return pose


def downhill_spawn(world, vehicle, rng, cfg) -> np.ndarray:
    """A free spawn pose on ground up to 30°, facing downhill (± 45°) where steeper than 15°."""
    pose = spawn_pose(world, vehicle, rng, replace(cfg, spawn_max_slope_deg=30.0))
    gy, gx = np.gradient(world.heights.astype(np.float64), world.grid.resolution)
    r, c = world.grid.xy_to_cell(pose[0], pose[1])
    if world.slope_deg()[r, c] > 15.0:
        pose[2] = math.atan2(-gy[r, c], -gx[r, c]) + rng.uniform(-math.pi / 4, math.pi / 4)
    return pose


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="demo")
    parser.add_argument("--vehicle", default="carla_cola")
    parser.add_argument("--runs", type=int, default=20)
    args = parser.parse_args()
    prof = get_profile(args.profile)
    world = get_world("training", prof)
    cfg = prof.collect
    turning = replace(cfg, turn_around_after_stall=True)
    variants = {"paper": (cfg, None), "turn-around": (turning, None),
                "turn-around + height-uniform spawns": (turning, height_uniform_spawn),
                "downhill spawns": (cfg, downhill_spawn)}
    print(f"{args.vehicle}, {args.runs} runs of seed 0 on the {args.profile} training world")
    print("| variant | driving s | samples | down >10° | >15° | >21° | up >10° | >21° |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, (config, spawn) in variants.items():
        grades, driven = [], 0.0
        for i in range(args.runs):
            seed = episode_seed(0, args.vehicle, i)
            start = None
            if spawn is not None:
                start = spawn(world, args.vehicle, np.random.default_rng(seed), config)
            ep = run_episode(world, args.vehicle, seed, config, start_pose=start, render=False)
            grades.append(heading_grades_deg(world, ep, cfg.patch_interval_s, cfg.patch_start_s))
            driven += ep.duration_s
        g = np.concatenate(grades)
        print(f"| {name} | {driven:.0f} | {len(g)} | {(g < -10).sum()} | {(g < -15).sum()} | "
              f"{(g < -21).sum()} | {(g > 10).sum()} | {(g > 21).sum()} |")


if __name__ == "__main__":
    main()
