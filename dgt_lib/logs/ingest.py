"""A drive log in, the paper's training data out: the BEV map of the log's RGB-D frames and
heading-aligned patches paired with locomotion labels (paper: Global Map, Locomotion,
Self-Supervised Label Generation), as the pipeline makes them from its own drives.

- **BEV**: a frame every ``collect.frame_spacing_m`` driven (as collection maps them),
  pixels up to ``collect.frame_max_depth_m``, each back-projected with the log's camera
  matrix and placed at the robot's pose at the frame's time composed with the camera's
  mount; on a grid over the driven area plus the depth range.
- **Labels**: the paper's L over the 1 s window around each patch time, with u the mean
  forward speed the robot was *commanded* in that window (the kit's own drives command a
  constant 5 m/s): L = exp(−((u·Δt − ‖Δx‖)/(u·Δt))² / 2σ²).
- **Runs**: the log splits into runs where the command drops below
  :data:`MIN_COMMAND_MPS` or the poses pause for more than :data:`GAP_S`; runs, not
  patches, are split 70/15/15 into train/validation/test.

Everything is stored under ``data/logs/<log name>/`` (``bev.npz``, ``dataset.npz``,
``log.json``), keyed by the log's name, size and modification time, the topics and the
settings: ingesting the same log again loads it.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from dgt_lib.core import artifacts
from dgt_lib.core.config import CollectConfig
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.logs.bag import BadLogError, open_log
from dgt_lib.logs.streams import (
    DEFAULT_TOPICS,
    LogTopics,
    Trajectory,
    TransformTree,
    camera_model,
    commanded_speed,
    frame_pairs,
    paired_frames,
    robot_trajectory,
)
from dgt_lib.perception.bev import BEV_RESOLUTION_M, BEVAccumulator, BEVMap
from dgt_lib.perception.dataset import (
    PatchDataset,
    label_window,
    patch_times,
    pose_at,
    split_by_trajectory,
)
from dgt_lib.perception.locomotion import MAX_ANGULAR_RATE_DPS, WINDOW_S, locomotion, mean_command
from dgt_lib.perception.patches import extract_patches

MIN_COMMAND_MPS = 0.5
"""A window whose mean commanded speed is below this is no drive, and gets no label [m/s]."""
GAP_S = 1.0
"""Poses further apart than this [s] end a run."""
MAX_SIDE_M = 4000.0
"""The largest side of a log's map [m] (a 0.4 m grid of 10,000² cells)."""
INGEST_FORMAT = 1
"""Version of what ingesting stores (part of its key)."""


def log_bev(reader: Any, topics: LogTopics, robot: Trajectory, cfg: CollectConfig
            ) -> tuple[BEVMap, int]:
    """The BEV map of the log's frames (module docstring) and how many frames it used."""
    k, camera_frame = camera_model(reader, topics.camera_info)
    tree = _tree(reader)
    mount = tree.trajectory(topics.base_frame, camera_frame)
    pairs = frame_pairs(reader, topics)
    depth_t = np.array(sorted(t for t in pairs if robot.covers(t)))
    if len(depth_t) == 0:
        raise BadLogError(f"the camera's images and {robot.what} never overlap in time "
                          f"(images at {min(pairs, default=0):.1f} s…, poses at "
                          f"{robot.time_s[0]:.1f}–{robot.time_s[-1]:.1f} s)")
    xy = robot.at(depth_t)[:, :2, 3]
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    chosen, next_m = [], 0.0
    for t, s in zip(depth_t, travelled, strict=True):
        if s >= next_m:
            chosen.append(float(t))
            next_m = s + cfg.frame_spacing_m
    acc = BEVAccumulator(_grid(robot, cfg.frame_max_depth_m))
    for t, rgb, depth in paired_frames(reader, topics, {t: pairs[t] for t in chosen}):
        world_cam = robot.at(t) @ mount.at(t)
        pts, cols = _back_project(rgb, depth, k, cfg.frame_max_depth_m)
        acc.add_points(pts @ world_cam[:3, :3].T + world_cam[:3, 3], cols)
    return acc.result(), len(chosen)


def _back_project(rgb: np.ndarray, depth: np.ndarray, k: np.ndarray, max_depth_m: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Points (N, 3) in the camera's optical frame (x right, y down, z ahead) [m] and
    their colours in 0..1, of the pixels with a depth up to ``max_depth_m``."""
    if rgb.shape[:2] != depth.shape:
        raise BadLogError(f"colour {rgb.shape[:2]} and depth {depth.shape} images differ in "
                          "size: the depth must be registered to the colour camera")
    fx, fy, cx, cy = k
    v, u = np.nonzero(depth <= max_depth_m)  # NaN compares False
    z = depth[v, u].astype(np.float64)
    pts = np.stack([(u - cx) / fx * z, (v - cy) / fy * z, z], axis=1)
    return pts, rgb[v, u].astype(np.float32) / 255.0


def _grid(robot: Trajectory, reach_m: float):
    """The 0.4 m grid over the driven area plus ``reach_m`` (cells aligned to 0.4 m)."""
    from dgt_lib.perception.bev import bev_grid

    xy = robot.poses[:, :2, 3]
    lo = np.floor((xy.min(axis=0) - reach_m - 2.0) / BEV_RESOLUTION_M) * BEV_RESOLUTION_M
    hi = xy.max(axis=0) + reach_m + 2.0
    if max(hi - lo) > MAX_SIDE_M:
        raise BadLogError(f"the log's drive spans {max(hi - lo):,.0f} m; at most "
                          f"{MAX_SIDE_M:,.0f} m fit one map")
    return bev_grid((lo[0], hi[0], lo[1], hi[1]))


def log_patches(robot: Trajectory, command: tuple[np.ndarray, np.ndarray], bev: BEVMap,
                cfg: CollectConfig, seed: int = 0) -> PatchDataset:
    """Patches and labels of every run of the log (module docstring), split by run."""
    t, poses = robot.time_s, robot.poses
    pose = np.stack([poses[:, 0, 3], poses[:, 1, 3],
                     np.arctan2(poses[:, 1, 0], poses[:, 0, 0])], axis=1)
    valid = angular_rate_dps(robot) <= MAX_ANGULAR_RATE_DPS
    cmd_t, cmd_v = command
    u_now = np.interp(t, cmd_t, cmd_v)  # a zero-order hold read at the pose times
    moving = u_now >= MIN_COMMAND_MPS
    run = np.cumsum(np.concatenate([[1], (np.diff(t) > GAP_S) | np.diff(moving.astype(int))
                                    != 0]))
    parts = []
    for r in np.unique(run[moving]):
        idx = np.nonzero(run == r)[0]
        if len(idx) < 2:
            continue
        tr = t[idx]
        at = tr[0] + patch_times(tr - tr[0], valid[idx], cfg.patch_interval_s,
                                 cfg.patch_start_s, WINDOW_S)
        start, end = label_window(tr, at, WINDOW_S)
        u = mean_command(cmd_t, cmd_v, start, end)
        at, start, end, u = (a[u >= MIN_COMMAND_MPS] for a in (at, start, end, u))
        if len(at) == 0:
            continue
        dx = [np.interp(end, tr, pose[idx, k]) - np.interp(start, tr, pose[idx, k])
              for k in (0, 1)]
        labels = locomotion(np.hypot(*dx), end - start, u=u)
        cut = pose_at(tr, pose[idx], at)
        patches, observed = extract_patches(bev, cut)
        parts.append((patches, observed, labels, cut, np.full(len(at), len(parts), np.int32)))
    if not parts:
        raise BadLogError("the log has no stretch of driving long enough for a label "
                          f"(commanded ≥ {MIN_COMMAND_MPS} m/s for more than "
                          f"{cfg.patch_start_s + WINDOW_S:.0f} s)")
    patches, observed, labels, cut, traj = (np.concatenate(p) for p in zip(*parts, strict=True))
    vehicle = np.zeros(len(labels), np.int8)
    return PatchDataset(patches=patches.astype(np.float16), observed=observed,
                        labels=labels.astype(np.float32), vehicle=vehicle, trajectory=traj,
                        pose=cut.astype(np.float32),
                        split=split_by_trajectory(traj, vehicle, seed=seed))


def angular_rate_dps(robot: Trajectory, baseline_s: float = 0.1) -> np.ndarray:
    """The body's angular rate [°/s] at each pose: odometry's, or the attitude's change
    over about ``baseline_s`` around it (a pose source without rates, ``/tf``)."""
    if robot.rate_dps is not None:
        return robot.rate_dps
    t, rot = robot.time_s, robot.poses[:, :3, :3]
    lo = np.clip(np.searchsorted(t, t - 0.5 * baseline_s), 0, len(t) - 1)
    hi = np.clip(np.searchsorted(t, t + 0.5 * baseline_s), 0, len(t) - 1)
    cos = (np.einsum("nij,nij->n", rot[hi], rot[lo]) - 1.0) / 2.0
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)) / np.maximum(t[hi] - t[lo], 1e-9))


def _tree(reader: Any) -> TransformTree:
    tree = TransformTree()
    tree.add(reader, "/tf_static", static=True)
    tree.add(reader, "/tf", static=False)
    return tree


def ingest(path: str | Path, vehicle: VehicleSpec, topics: LogTopics = DEFAULT_TOPICS,
           cfg: CollectConfig | None = None) -> dict[str, Any]:
    """The log at ``path`` driven by ``vehicle``: its BEV map and dataset, built or loaded
    from ``data/logs/<name>/`` (module docstring). Returns a summary (also ``log.json``)."""
    path, cfg = Path(path), cfg or CollectConfig()
    stat = path.stat() if path.exists() else None
    key = {"format": INGEST_FORMAT, "log": [path.name, stat and stat.st_size,
                                             stat and stat.st_mtime_ns],
           "topics": topics, "collect": cfg, "vehicle": vehicle}
    folder = path.name.replace(".", "_")
    built: dict[str, Any] = {}

    def build_bev() -> dict[str, np.ndarray]:
        with open_log(path) as reader:
            robot = robot_trajectory(reader, topics, _tree(reader))
            command = commanded_speed(reader, topics.cmd)
            bev, frames = log_bev(reader, topics, robot, cfg)
        built.update(robot=robot, command=command, frames=frames)
        return bev.to_arrays()

    try:
        bev = BEVMap.from_arrays(artifacts.ensure(f"{folder}/bev.npz", key, build_bev,
                                                  profile="logs"))

        def build_dataset() -> dict[str, np.ndarray]:
            if "robot" not in built:
                with open_log(path) as reader:
                    built.update(robot=robot_trajectory(reader, topics, _tree(reader)),
                                 command=commanded_speed(reader, topics.cmd))
            return log_patches(built["robot"], built["command"], bev, cfg).to_arrays()

        ds = PatchDataset.from_arrays(artifacts.ensure(f"{folder}/dataset.npz", key,
                                                       build_dataset, profile="logs"))
    except BadLogError:  # nothing half-written stays: the folder goes if it holds only locks
        where = artifacts.profile_dir("logs") / folder
        if where.is_dir() and all(f.suffix == ".lock" for f in where.iterdir()):
            shutil.rmtree(where, ignore_errors=True)
        raise
    summary = {"log": str(path), "vehicle": vehicle.name, "topics": vars(topics),
               "folder": str(artifacts.profile_dir("logs") / folder),
               "map_cells_observed": int(bev.observed.sum()),
               "patches": {name: int((ds.split == i).sum())
                           for i, name in enumerate(("train", "val", "test"))},
               "runs": int(len(np.unique(ds.trajectory))),
               "label_mean": round(float(ds.labels.mean()), 3)}
    artifacts.save(artifacts.profile_dir("logs") / folder / "log.json", summary)
    return summary


def summary_text(summary: dict[str, Any]) -> str:
    """The summary of :func:`ingest` as a few lines for the terminal."""
    p = summary["patches"]
    alone = ("\none run, so every patch is in the training split: a log of several runs "
             "(drives with a stop between them) holds some out") if summary["runs"] < 2 else ""
    return (f"{summary['log']} driven by {summary['vehicle']}: {summary['runs']} runs, "
            f"{p['train']} / {p['val']} / {p['test']} patches (train / val / test), "
            f"mean L {summary['label_mean']}, {summary['map_cells_observed']:,} map cells "
            f"observed{alone}\nstored in {summary['folder']}\n" + json.dumps(summary["topics"]))
