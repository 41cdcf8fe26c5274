"""Does the model know what carla_cola's Route B descent costs? Measured against predicted:

    .venv/bin/python studies/diagnose_descent.py --profile demo

1. **Measured.** carla_cola drives Route B of the hill world up and down in the simulator
   (pure pursuit + the collection's PID speed controller at 5 m/s, the way the data were
   collected), on three lateral offsets (−1, 0, +1 m), and the locomotion L (paper's
   formula, 1 s centred window) is computed along each run; L is averaged over the steep
   section. The physics does not depend on the run seed, so this is done once.
2. **Predicted.** Per run seed, each model's L̂ = 1 − C along the same runs, C read from
   the cached directional costmap at the heading layer nearest the direction of travel.
3. **Training labels.** Per run seed, carla_cola's patches whose height falls (descents)
   or rises (ascents) along the forward axis at the steep section's grade ±5°: how many,
   and their mean L.

If the measured descent L is high but L̂ low, the model, not the physics, made DGT-Map avoid
Route B downhill; the labels of similar patches say whether the data taught it that.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, get_profile
from dgt_lib.core.geometry import nearest_heading_bin
from dgt_lib.navigation.drive import Trajectory, follow_path
from dgt_lib.perception.bev import BEVMap
from dgt_lib.perception.dataset import PatchDataset
from dgt_lib.perception.locomotion import locomotion_signal
from dgt_lib.perception.patches import forward_grade
from dgt_lib.stages.collect import bev_relpath
from dgt_lib.stages.dataset import DATASET_RELPATH
from dgt_lib.stages.paths import data_dir
from dgt_lib.world.simulator import Simulator
from dgt_lib.world.terrain import HILL_STEEP_DEG, get_world

VEHICLE = "carla_cola"
OFFSETS_M = (-1.0, 0.0, 1.0)
METHODS = ("dgt", f"single_{VEHICLE}")  # cached costmap files of the hill world


def steep_section(world, traj: Trajectory) -> np.ndarray:
    """(N,) bool: samples between the landmarks of Route B's steep section (± 2 m in y)."""
    y0 = world.landmarks["B_steep_bottom"][1] - 2.0
    y1 = world.landmarks["B_steep_top"][1] + 2.0
    y = traj.position[:, 1]
    return (y >= y0) & (y <= y1)


def drive_route_b(world, direction: str) -> list[tuple[float, Trajectory]]:
    """carla_cola along Route B (``"ascent"`` base → summit, ``"descent"`` back), per offset."""
    route = np.asarray(world.routes["B"], np.float64)
    if direction == "descent":
        route = route[::-1]
    runs = []
    sim = Simulator(world, VEHICLE)
    try:
        for dx in OFFSETS_M:
            runs.append((dx, follow_path(sim, route + [dx, 0.0], max_time_s=90.0)))
    finally:
        sim.close()
    return runs


def measured_l(traj: Trajectory) -> np.ndarray:
    """(N,) the paper's locomotion L along a run (1 s centred window, u = 5 m/s)."""
    return locomotion_signal(traj.time_s, traj.position[:, :2])


def predicted_l(cost: np.ndarray, grid, traj: Trajectory) -> np.ndarray:
    """(N,) L̂ = 1 − C along a run: C at each sample's cell, heading layer nearest its yaw."""
    r, c = grid.xy_to_cell(traj.position[:, 0], traj.position[:, 1])
    r = np.clip(r, 0, cost.shape[1] - 1)
    c = np.clip(c, 0, cost.shape[2] - 1)
    return 1.0 - cost[nearest_heading_bin(traj.yaw, cost.shape[0]), r, c]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="demo")
    args = parser.parse_args()
    prof = get_profile(args.profile)
    hill = get_world("hill", prof)
    grade = math.tan(math.radians(HILL_STEEP_DEG))
    lo, hi = math.tan(math.radians(HILL_STEEP_DEG - 5)), math.tan(math.radians(HILL_STEEP_DEG + 5))

    print(f"1. measured: {VEHICLE} on Route B (steep section {HILL_STEEP_DEG:.0f}°, grade "
          f"{grade:.2f}), lateral offsets {OFFSETS_M} m")
    runs = {d: drive_route_b(hill, d) for d in ("ascent", "descent")}
    for d, rs in runs.items():
        for dx, tr in rs:
            steep = steep_section(hill, tr)
            ell = measured_l(tr)
            speed = np.abs(tr.speed_mps[steep])
            print(f"   {d:<7} offset {dx:+.0f} m: {tr.end_reason:<11} steep-section L mean "
                  f"{ell[steep].mean() if steep.any() else float('nan'):.2f} "
                  f"min {ell[steep].min() if steep.any() else float('nan'):.2f}, "
                  f"speed {speed.min() if steep.any() else 0:.1f}–"
                  f"{speed.max() if steep.any() else 0:.1f} m/s")

    for run in prof.seed_profiles():
        root = data_dir(run)
        if not (root / "costmaps" / "hill" / "dgt.npz").exists():
            print(f"seed {run.seed}: no hill costmaps under {root} (run dgt reproduce)")
            continue
        print(f"seed {run.seed}:")
        grid = BEVMap.from_arrays(artifacts.load(root / bev_relpath("hill"))).grid
        for method in METHODS:
            arrays = artifacts.load(root / "costmaps" / "hill" / f"{method}.npz")
            cost = arrays[VEHICLE] if VEHICLE in arrays else arrays["cost"]
            parts = []
            for d, rs in runs.items():
                lhat = [predicted_l(cost, grid, tr)[steep_section(hill, tr)].mean()
                        for _, tr in rs if steep_section(hill, tr).any()]
                parts.append(f"{d} L̂ {np.mean(lhat):.2f}")
            print(f"   2. predicted ({method:<6}): " + ", ".join(parts))
        ds = PatchDataset.from_arrays(artifacts.load(root / DATASET_RELPATH))
        own = ds.vehicle == VEHICLES.index(VEHICLE)
        g = forward_grade(ds.patches[own])
        labels = ds.labels[own]
        for d, sel in (("descent", (g <= -lo) & (g >= -hi)), ("ascent", (g >= lo) & (g <= hi))):
            mean = f"{labels[sel].mean():.2f}" if sel.any() else "—"
            print(f"   3. training patches, {d:<7} at {HILL_STEEP_DEG - 5:.0f}–"
                  f"{HILL_STEEP_DEG + 5:.0f}°: n = {int(sel.sum())}, mean L {mean}")


if __name__ == "__main__":
    main()
