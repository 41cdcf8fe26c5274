"""Incremental costmap: per-frame update time against a full recompute.

Target: an update after one new RGB-D frame ≤ 100 ms for one vehicle on 2 cores.

A jeep explores the profile's eval world from nothing observed
(:func:`dgt_lib.beyond.explore.explore`: a frame a second, Hybrid A* replanning, MPPI).
After every frame the incremental update's wall and CPU time (``time.process_time``) are
recorded (``explore`` calls ``refresh``, which passes the changed cells as a mask; a
shadow costmap given only their bounding box is timed beside it), the K = 8 layers are
recomputed from scratch with ``directional_costmap`` on the same BEV (same lattice
stride, ``skip_unobserved``; timed the same way), and the largest and mean |ΔC| between
the two are kept. Prints median and p90 of both, the equality error and the machine's
load average (the numbers mean little on a loaded machine).

    .venv/bin/python benchmarks/bench_incremental.py [--profile smoke]
        [--model data/demo/seed-0/models/multitask.pt] [--tolerance 0.1] [--stride 6 3]
        [--width 16]

Without ``--model`` it uses the profile's trained multitask model (smoke: width 8);
a checkpoint (e.g. the `paper` profile's width-64
``data/paper/seed-0/models/multitask.pt``) times the paper's network. ``--pooled PATH``
drives with a :class:`~dgt_lib.beyond.pooled.PooledNet` saved by
``studies/eval_pooled.py`` instead: every window, evaluated densely
(:class:`~dgt_lib.beyond.incremental.DenseIncrementalCostmap`), compared with
``directional_costmap_dense`` of the same map (``--stride`` does not apply).
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import torch  # noqa: E402

import dgt_lib as dgt  # noqa: E402
from dgt_lib.beyond.dense import directional_costmap_dense  # noqa: E402
from dgt_lib.beyond.explore import ExploreConfig, explore  # noqa: E402
from dgt_lib.beyond.incremental import (  # noqa: E402
    DenseIncrementalCostmap,
    IncrementalCostmap,
    changed_cells,
)
from dgt_lib.beyond.pooled import PooledNet, bfloat16_copy  # noqa: E402
from dgt_lib.core import artifacts  # noqa: E402
from dgt_lib.core.config import VEHICLES  # noqa: E402
from dgt_lib.learning.checkpoints import load_checkpoint  # noqa: E402
from dgt_lib.learning.run import train_model  # noqa: E402
from dgt_lib.learning.training import evaluate, predict  # noqa: E402
from dgt_lib.mapping.costmap import directional_costmap  # noqa: E402
from dgt_lib.perception.bev import bev_grid  # noqa: E402
from dgt_lib.perception.dataset import PatchDataset  # noqa: E402
from dgt_lib.stages.costmaps import ensure_tau_s, load_model  # noqa: E402
from dgt_lib.stages.dataset import DATASET_RELPATH  # noqa: E402
from dgt_lib.stages.paths import data_dir  # noqa: E402


def _narrower(profile, model, width: int):
    """Train the profile's multi-task model again at ``width`` on its cached dataset; print
    both models' test MSE / Spearman ρ per vehicle (the accuracy a faster update costs)."""
    ds = PatchDataset.from_arrays(artifacts.load(data_dir(profile) / DATASET_RELPATH))
    wall = time.perf_counter()
    result = train_model(ds, replace(profile.train, width=width), seed=profile.seed,
                         progress=False)
    print(f"trained width {width} in {time.perf_counter() - wall:.0f} s; test MSE / ρ:")
    test = ds.part("test")
    for name, m in ((f"width {model.width} (the profile's)", model),
                    (f"width {width}", result.model)):
        metrics = evaluate(m, test)
        print(f"  {name}: " + ", ".join(f"{v} {x['mse']:.4f} / {x['spearman']:.2f}"
                                        for v, x in metrics.items()))
    return result.model


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", default="smoke")
    ap.add_argument("--model", default=None, help="a checkpoint (default: the profile's)")
    ap.add_argument("--vehicle", default="jeep")
    ap.add_argument("--tolerance", type=float, default=0.0,
                    help="ExploreConfig.change_tolerance (0: exact updates)")
    ap.add_argument("--stride", type=int, nargs=2, default=None,
                    help="lattice stride (default: the profile's costmap stride)")
    ap.add_argument("--pooled", default=None,
                    help="a PooledNet state dict (studies/eval_pooled.py): dense updates")
    ap.add_argument("--bf16", action="store_true",
                    help="with --pooled: drive and recompute with its bfloat16 copy")
    ap.add_argument("--width", type=int, default=None,
                    help="first train a multi-task model of this width (the profile's recipe "
                         "otherwise) on the profile's cached dataset and drive with it")
    args = ap.parse_args()
    profile = dgt.get_profile(args.profile)
    world = dgt.get_world("eval", profile)
    model = (load_checkpoint(args.model).model if args.model
             else load_model(profile, progress=False))
    if args.width is not None:
        model = _narrower(profile, model, args.width)
    head = VEHICLES.index(args.vehicle)

    def locomotion(patches: np.ndarray) -> np.ndarray:
        return predict(model, patches)[:, [head]]

    grid = bev_grid(world.grid.extent)
    if args.pooled:  # drive with the PooledNet, densely; compare with its dense costmap
        model = PooledNet.from_state_dict(torch.load(args.pooled, weights_only=True))
        if args.bf16:
            model = bfloat16_copy(model)
        pooled_head = model.head_index(args.vehicle)

    stride = tuple(args.stride) if args.stride else profile.costmap.stride
    cfg = ExploreConfig(stride=stride, time_limit_s=60.0, change_tolerance=args.tolerance,
                        mppi_batch_size=profile.mppi.batch_size)
    full_wall, full_cpu, error, mean_error = [], [], [], []
    by_box = (DenseIncrementalCostmap(grid, model, cfg.n_headings, vehicles=(args.vehicle,))
              if args.pooled else
              IncrementalCostmap(grid, locomotion, 1, cfg.n_headings, stride=cfg.stride))
    box_stats, previous = [], [None]

    def compare(bev, costmap) -> None:
        box_stats.append(by_box.update(bev, changed_cells(previous[0], bev)))
        previous[0] = bev
        wall, cpu = time.perf_counter(), time.process_time()
        if args.pooled:
            full = directional_costmap_dense(bev, model, cfg.n_headings,
                                             progress=False)[[pooled_head]]
        else:
            full = directional_costmap(bev, locomotion, cfg.n_headings, stride=cfg.stride,
                                       skip_unobserved=True, progress=False)
        full_wall.append(time.perf_counter() - wall)
        full_cpu.append(time.process_time() - cpu)
        error.append(float(np.abs(full - costmap.cost).max()))
        mean_error.append(float(np.abs(full - costmap.cost)[:, :, bev.observed].mean()))

    x0, x1, y0, y1 = world.interior
    load_before = os.getloadavg()
    result = explore(world, args.vehicle, model if args.pooled else locomotion,
                     (x0 + 10, y0 + 10, np.pi / 4), (x1 - 10, y1 - 10), ensure_tau_s(profile),
                     cfg=cfg,
                     planner=profile.planner, on_update=compare)
    load_after = os.getloadavg()
    frames = result.frames
    rows = {
        "incremental update, wall": [f.update.wall_s for f in frames],
        "incremental update, CPU": [f.update.cpu_s for f in frames],
        "incremental update given the box only, wall": [b.wall_s for b in box_stats],
        "full recompute, wall": full_wall,
        "full recompute, CPU": full_cpu,
        "BEV aggregation (whole grid), wall": [f.bev_s for f in frames],
    }
    h, w = result.bev.grid.shape
    width = getattr(model, "width", None) or "?"
    how = (f"PooledNet depth {model.depth}, dense{', bfloat16' if args.bf16 else ''}"
           if args.pooled else f"stride {cfg.stride}")
    print(f"eval world {world.grid.extent[1]:.0f} m, BEV {h}×{w} cells, K = {cfg.n_headings}, "
          f"{how}, change tolerance {cfg.change_tolerance}, "
          f"vehicle {args.vehicle}, model width {width}, "
          f"torch threads {os.environ.get('OMP_NUM_THREADS', 'default')}; "
          f"{len(frames)} frames, outcome {result.outcome.reason}")
    print(f"load average (1, 5, 15 min) before {tuple(round(v, 2) for v in load_before)}, "
          f"after {tuple(round(v, 2) for v in load_after)} on {os.cpu_count()} cores")
    print("| per frame | median [ms] | p90 [ms] |\n|---|---|---|")
    for name, values in rows.items():
        ms = np.asarray(values) * 1e3
        print(f"| {name} | {np.median(ms):.0f} | {np.percentile(ms, 90):.0f} |")
    windows = [f.update.windows for f in frames]
    print(f"| windows re-evaluated (8 headings) | {np.median(windows):.0f} | "
          f"{np.percentile(windows, 90):.0f} |")
    windows = [b.windows for b in box_stats]
    print(f"| windows re-evaluated given the box only | {np.median(windows):.0f} | "
          f"{np.percentile(windows, 90):.0f} |")
    speedup = np.median(full_wall) / np.median(rows["incremental update, wall"])
    print(f"speed-up (median wall) {speedup:.1f}×; |C_incremental − C_full| over all "
          f"frames: max {max(error):.1e}, largest per-frame mean over observed cells "
          f"{max(mean_error):.1e}")


if __name__ == "__main__":
    main()
