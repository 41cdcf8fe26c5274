"""The rerun recording of an exploration run (:mod:`dgt_lib.beyond.explore`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dgt_lib.core.config import Profile
from dgt_lib.viz.recording import Recording
from dgt_lib.world.worlds import World

if TYPE_CHECKING:  # an annotation only: importing it pulls in MPPI (~0.7 s)
    from dgt_lib.beyond.explore import ExploreResult


def write_exploration(path: str | Path, world: World, result: ExploreResult, vehicle: str,
                      profile: Profile, *, max_snapshots: int = 20) -> Path:
    """The recording of a :func:`~dgt_lib.beyond.explore.explore` run: the terrain,
    the vehicle's costmap growing over ``sim_time`` (at most ``max_snapshots`` mapping
    steps, evenly spaced, the last included), the path followed after each replan, the
    track, the final BEV and a note with the update times. Returns the file's path."""
    frames = result.frames
    keep = sorted(set(np.linspace(0, len(frames) - 1, min(max_snapshots, len(frames)))
                      .round().astype(int).tolist())) if frames else []
    grid = result.bev.grid if result.bev is not None else world.grid
    with Recording(path, "exploration", profile) as rec:
        rec.log_terrain(world.heights, world.colors, world.grid)
        for i in keep:
            rec.log_costmap(frames[i].cost, grid, vehicle, time_s=frames[i].time_s)
        replans = [f for i, f in enumerate(frames)
                   if i == 0 or not np.array_equal(f.path, frames[i - 1].path)]
        for f in replans:
            xy = f.path[:, :2]
            z = world.height_at(xy[:, 0], xy[:, 1]) + 0.5
            rec.log_path("planned", np.column_stack([xy, z]), time_s=f.time_s)
        traj = result.trajectory
        rec.log_trajectory(vehicle, traj[:, 0], traj[:, 1:4], vehicle=vehicle, yaw=traj[:, 4])
        if result.bev is not None:
            rec.log_bev(result.bev.channels, result.bev.observed)
        ms = np.array([f.update.wall_s for f in frames]) * 1e3
        rec.log_text("exploration", (
            f"**{result.outcome.reason}** after {result.outcome.duration_s:.1f} s, "
            f"{len(frames)} frames, {len(result.replans)} plans. Costmap update per frame: "
            f"median {np.median(ms):.0f} ms, p90 {np.percentile(ms, 90):.0f} ms (wall)."
            if frames else f"**{result.outcome.reason}**, no frames"))
    return Path(path)
