"""Does the occupancy map leave ``eval_hazard``'s ditches free? (docs/worlds.md)

For a profile: the share of ditch cells (cells the ditches cut) steeper than τ_s in the
true heights and in the BEV (occupied), and, for ``--queries`` jeep queries drawn by
Experiment 3's rule, how many of Binary's Hybrid A* plans (occupancy only, a zero costmap)
cross a cell the jeep cannot cross (``vehicle_hazards(..., bumpers=True)``). Builds the
BEV maps it needs (the survey of ``eval_hazard``, hill and ridge for τ_s); runs no trial.
``--publish`` writes the record whose table docs/worlds.md quotes.

    .venv/bin/python studies/eval_hazard_occupancy.py [--profile smoke] [--queries 20] [--publish]
"""

from __future__ import annotations

import numpy as np
from runner import Study

from dgt_lib.core.config import get_profile
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.evaluation.hazards import hazard_map, vehicle_hazards
from dgt_lib.evaluation.queries import draw_random_queries
from dgt_lib.mapping.baselines import binary_costmap
from dgt_lib.navigation.planner import HybridAStar
from dgt_lib.perception.bev import GRADIENT
from dgt_lib.records.study import table
from dgt_lib.stages.experiments import trial_maps
from dgt_lib.world.terrain import ditch_count, ditch_cuts, get_world


def main() -> None:
    study = Study("eval_hazard_occupancy", __doc__, profile="smoke", per_seed=False)
    study.parser.add_argument("--queries", type=int, default=20)
    args = study.parse()
    prof = get_profile(args.profile).with_overrides({"experiments.eval_hazard_world": True})
    world, base = get_world("eval_hazard", prof), get_world("eval", prof)
    maps = trial_maps("eval_hazard", "binary", "jeep", prof)
    cut = ditch_cuts(base, ditch_count(prof.worlds.eval_size_m),
                     prof.worlds.eval_seed)[1] > 0  # the generator's own cells
    gy, gx = np.gradient(world.heights.astype(np.float64), world.resolution)
    steep = np.hypot(gx, gy) > maps.tau_s
    occupied = maps.bev.channels[GRADIENT] > maps.tau_s
    jeep = vehicle_hazards(world, "jeep", bumpers=True)
    draw = draw_random_queries(maps, args.queries, prof.experiments, prof.seed, "jeep",
                               hazards=hazard_map(world, ("jeep", "vw_van")),
                               planner_cfg=prof.planner)
    planner = HybridAStar.for_vehicle(binary_costmap(maps.grid.shape), maps.occupancy,
                                      maps.grid, get_vehicle("jeep"), prof.planner)
    straight = planned = crossing = 0
    for q in draw.queries:
        t = np.linspace(0.0, 1.0, 200)
        r, c = world.grid.xy_to_cell(q.start[0] + t * (q.goal[0] - q.start[0]),
                                     q.start[1] + t * (q.goal[1] - q.start[1]))
        straight += bool(jeep[r, c].any())
        plan = planner.plan(q.start, q.goal)
        if plan.success:
            planned += 1
            r, c = world.grid.xy_to_cell(plan.path[:, 0], plan.path[:, 1])
            crossing += bool(jeep[r, c].any())
    n = len(draw.queries)
    study.finish({"occupancy": table(
        f"The ditches of eval_hazard in the occupancy map (τ_s {maps.tau_s:.3f} m/m) and "
        f"{n} jeep queries drawn by Experiment 3's rule",
        ["ditch cells", "steeper than τ_s (true heights)", "occupied (BEV)",
         "occupied elsewhere", "straight lines crossing a jeep hazard",
         "Binary's plans crossing one"],
        [[f"{int(cut.sum()):,}", f"{100 * steep[cut].mean():.0f} %",
          f"{100 * occupied[cut].mean():.0f} %", f"{100 * occupied[~cut].mean():.0f} %",
          f"{straight} of {n}", f"{crossing} of {planned}"]])}, seeds=[prof.seed])


if __name__ == "__main__":
    main()
