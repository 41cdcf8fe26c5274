"""Why does DGT-Map's mercedes_van cross the ridge at the sharp section? Per run seed:

    .venv/bin/python studies/diagnose_ridge.py --profile demo

reads the cached `dgt reproduce` artifacts of each seed (nothing is trained) and prints
1. each head's DGT cost (heading north, 5 × 5 cells) at the ridge world's landmarks — the
   two crossings and the flat start/goal areas south and north of the ridge;
2. the van's patches by relief along the patch's forward axis (max − min of H̄ over the
   centre columns) and steepest ‖∇H̄‖: how many, their mean L, how many with L < 0.3.
A head that rates flat ground as costly makes every route look alike to the planner, which
then takes the shortest — over the sharp ridge.
"""

from __future__ import annotations

import argparse

import numpy as np

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, get_profile
from dgt_lib.perception.bev import BEVMap
from dgt_lib.perception.dataset import PatchDataset
from dgt_lib.stages.collect import bev_relpath
from dgt_lib.stages.dataset import DATASET_RELPATH
from dgt_lib.stages.paths import data_dir
from dgt_lib.world.terrain import get_world

LANDMARKS = ("sharp_crossing", "smooth_crossing", "south", "north")
NORTH = 2  # heading layer θ = π/2 of K = 8


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", default="demo")
    args = parser.parse_args()
    prof = get_profile(args.profile)
    ridge = get_world("ridge", prof)
    for run in prof.seed_profiles():
        root = data_dir(run)
        if not (root / "costmaps" / "ridge" / "dgt.npz").exists():
            print(f"seed {run.seed}: no ridge costmaps under {root} (run dgt reproduce)")
            continue
        bev = BEVMap.from_arrays(artifacts.load(root / bev_relpath("ridge")))
        cost = artifacts.load(root / "costmaps" / "ridge" / "dgt.npz")
        print(f"seed {run.seed}: DGT cost heading north at the ridge world's landmarks")
        for v in ("jeep", "mercedes_van"):
            cells = []
            for key in LANDMARKS:
                r, c = bev.grid.xy_to_cell(*ridge.landmarks[key])
                cells.append(f"{key} {cost[v][NORTH, r - 2:r + 3, c - 2:c + 3].mean():.2f}")
            print(f"  {v:<13} " + ", ".join(cells))
        ds = PatchDataset.from_arrays(artifacts.load(root / DATASET_RELPATH))
        own = ds.vehicle == VEHICLES.index("mercedes_van")
        heights = ds.patches[own, 3].astype(np.float32)[:, :, 2:5].mean(axis=2)  # (n, 22)
        relief = np.nanmax(heights, axis=1) - np.nanmin(heights, axis=1)
        steepest = np.nanmax(ds.patches[own, 5].astype(np.float32).reshape(own.sum(), -1), 1)
        labels = ds.labels[own]
        groups = {"flat (relief < 0.3 m)": relief < 0.3,
                  "relief ≥ 0.5 m, smooth (max ‖∇H̄‖ < 0.35)": (relief >= 0.5) & (steepest < 0.35),
                  "relief ≥ 0.5 m, sharp (max ‖∇H̄‖ ≥ 0.5)": (relief >= 0.5) & (steepest >= 0.5)}
        print(f"  mercedes_van patches: {own.sum()}")
        for name, m in groups.items():
            mean = f"{labels[m].mean():.2f}" if m.any() else "—"
            print(f"    {name:<42} {m.sum():5d}  mean L {mean}  L < 0.3: {(labels[m] < 0.3).sum()}")


if __name__ == "__main__":
    main()
