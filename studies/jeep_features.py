"""What stops the jeep in MuJoCo on terrain the occupancy map leaves free: crests and
V-ditches driven straight across at a fixed speed command (no planner, no controller, no
costmap), the premise of the ``eval_hazard`` world (docs/worlds.md).

1. A 1.5 m crest across a flat map with flanks of 24–40°, at 2 and 5 m/s, perpendicular.
2. The ditches of ``add_ditches`` (sizes from ``ditch_parameters``), one per seed on a flat
   100 m map, at 5 m/s from both sides, perpendicular and 30° and 60° off it.

"Crossed" = the vehicle ends more than 3 m past the feature's line; else it was stopped.

    .venv/bin/python studies/jeep_features.py [--seeds N] [--publish]

``--publish`` writes the record whose tables docs/worlds.md quotes.
"""

from __future__ import annotations

import numpy as np
from runner import Study

from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.navigation.drive import drive_straight
from dgt_lib.records.study import table
from dgt_lib.world.simulator import Simulator
from dgt_lib.world.terrain import add_ditches, ditch_cuts, ditch_parameters
from dgt_lib.world.worlds import World, from_heightmap

JEEP = get_vehicle("jeep")


def crossing(world: World, centre, normal_rad: float, speed_mps: float) -> tuple[float, float]:
    """Drive straight from 8 m before ``centre`` along ``normal_rad`` for 8 s: the signed
    distance [m] of the end past the feature's line, and the final speed [m/s]."""
    n = np.array([np.cos(normal_rad), np.sin(normal_rad)])
    start = np.asarray(centre) - 8.0 * n
    sim = Simulator(world, JEEP)
    try:
        tr = drive_straight(sim, start[0], start[1], normal_rad, speed_mps=speed_mps,
                            duration_s=8.0)
    finally:
        sim.close()
    return float((tr.position[-1, :2] - centre) @ n), float(tr.speed_mps[-1])


def stopped(past_m: float, speed: float) -> bool:
    """Whether a :func:`crossing` ended before getting 3 m past the line."""
    return past_m < 3.0


def crests() -> dict:
    """A 1.5 m crest with each flank angle driven across at 2 and 5 m/s."""
    x = (np.arange(150) + 0.5) * 0.4
    rows = []
    for flank in (24.0, 30.0, 35.0, 40.0):
        h = np.clip(1.5 - np.abs(x - 30.0) * np.tan(np.radians(flank)), 0.0, None)
        world = from_heightmap(np.tile(h, (60, 1)), 0.4, name="crest")
        relief = np.tan(np.radians(flank)) * 0.5 * JEEP.wheelbase_m / JEEP.ground_clearance_m
        runs = {s: crossing(world, (30.0, 12.0), 0.0, s) for s in (2.0, 5.0)}
        out = [f"{s:.0f} m/s {'stopped' if stopped(*r) else 'crossed'} (end {r[0]:+.1f} m, "
               f"{r[1]:.2f} m/s)" for s, r in runs.items()]
        print(f"crest, flanks {flank:.0f}° (crest {relief:.2f} × clearance above the axle "
              f"chord): " + ", ".join(out))
        rows.append([f"{flank:.0f}°", f"{relief:.2f}", *out])
    return table("A 1.5 m crest driven straight across (end: metres past the crest line, "
                 "speed)", ["flanks", "crest above the axle chord [× clearance]", "at 2 m/s",
                            "at 5 m/s"], rows)


def ditches(seeds: int) -> dict:
    """The ditches of ``add_ditches``, one a seed, driven at 5 m/s from both sides."""
    flat = from_heightmap(np.zeros((250, 250)), 0.4, name="flat")
    par = ditch_parameters("jeep")
    print(f"ditches: flanks {par['flank_deg'][0]:.1f}–{par['flank_deg'][1]:.1f}°, depth "
          f"{par['depth_m'][0]:.2f}–{par['depth_m'][1]:.2f} m, at 5 m/s")
    counts: dict[int, list[bool]] = {0: [], 30: [], 60: []}
    for seed in range(seeds):
        world = add_ditches(flat, 1, seed, "one")
        cx, cy, ang = ditch_cuts(flat, 1, seed)[2][0]  # where add_ditches put it
        centre = np.array([cx, cy])
        for off, sign in ((o, s) for o in counts for s in (1, -1)):
            a = ang + sign * np.pi / 2 + np.radians(off)
            start = centre - 8.0 * np.array([np.cos(a), np.sin(a)])
            if not np.all((start > 3.0) & (start < 97.0)):
                continue  # the run-up would start off the map
            counts[off].append(stopped(*crossing(world, centre, a, 5.0)))
    for off, runs in counts.items():
        print(f"  {off:2d}° off perpendicular: stopped {sum(runs)} of {len(runs)}")
    return table(f"The ditches of add_ditches ({seeds} drawn; flanks {par['flank_deg'][0]:.1f}–"
                 f"{par['flank_deg'][1]:.1f}°, depth {par['depth_m'][0]:.2f}–"
                 f"{par['depth_m'][1]:.2f} m) driven at 5 m/s from both sides",
                 ["direction", "stopped"],
                 [[f"{off}° off perpendicular", f"{sum(runs)} of {len(runs)}"]
                  for off, runs in counts.items()])


def main() -> None:
    study = Study("jeep_features", __doc__, per_seed=False)
    study.parser.add_argument("--seeds", type=int, default=8,
                              help="ditches driven, one per seed (default 8)")
    args = study.parse()
    study.finish({"crests": crests(), "ditches": ditches(args.seeds)}, seeds=[])


if __name__ == "__main__":
    main()
