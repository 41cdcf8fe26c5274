"""How much of each profile's evaluation worlds Experiment 3's query rule calls hazardous,
and what share of candidate queries it keeps (dgt_lib/evaluation/hazards.py).

No artifacts: the rule reads only the world's true heights and the vehicles' specs. The
candidates are drawn as ``draw_random_queries`` draws them (start 10 m inside the map, a
distance uniform in ``eval_distance_m``, a uniform direction, the goal 10 m inside the map);
footprints and feasibility, which need the mapped occupancy, are not checked here — the
``dgt reproduce`` run's draw reports those (``QueryDraw.rejected``). Each profile gets a row
for ``eval`` (the paper's setup) and one for ``eval_hazard`` (``experiments.eval_hazard_world``):
there also the jeep's hazards with its bumper (``vehicle_hazards(..., bumpers=True)``, the
ditches) and the share of kept lines that cross one; and a row for the training world's
jeep hazards, the terrain its costmap learns from.

    .venv/bin/python studies/query_rule.py [PROFILE ...] [--candidates N]
"""

from __future__ import annotations

import argparse

import numpy as np

from dgt_lib.core.config import PROFILE_NAMES, get_profile
from dgt_lib.evaluation.experiments import EXPERIMENTS
from dgt_lib.evaluation.hazards import HazardMap, hazard_map, line_stats, vehicle_hazards
from dgt_lib.world.terrain import get_world


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("profiles", nargs="*", default=list(PROFILE_NAMES))
    ap.add_argument("--candidates", type=int, default=5000)
    args = ap.parse_args()
    _, vehicles, _ = EXPERIMENTS["experiment3"]
    for name in args.profiles:
        prof = get_profile(name)
        ex = prof.experiments
        for world_name in ("eval", "eval_hazard"):
            world = get_world(world_name, prof)
            hz = hazard_map(world, vehicles)
            per_vehicle = ", ".join(f"{v} {100 * vehicle_hazards(world, v).mean():.2f} %"
                                    for v in vehicles)
            jeep = HazardMap(world.grid, vehicle_hazards(world, "jeep", bumpers=True))
            st = line_stats(hz, jeep, ex.eval_distance_m, ex.eval_min_hazard_m, prof.seed,
                            args.candidates)
            print(f"{name}: {world_name} {world.grid.extent[1]:.0f} m, hazard cells "
                  f"{100 * hz.fraction:.2f} % ({per_vehicle}; jeep with its bumper "
                  f"{100 * jeep.fraction:.2f} %); of {len(st.lengths)} on-map candidates "
                  f"({ex.eval_distance_m[0]:.0f}–{ex.eval_distance_m[1]:.0f} m) the rule "
                  f"(≥ {ex.eval_min_hazard_m:g} m of hazard) keeps {100 * st.kept.mean():.0f} %; "
                  f"median hazard on the line {np.median(st.lengths):.1f} m; "
                  f"{100 * st.kept_crossing:.0f} % of the kept cross a jeep hazard")
        train = get_world("training", prof)
        print(f"{name}: training {train.grid.extent[1]:.0f} m, jeep hazard cells "
              f"{100 * vehicle_hazards(train, 'jeep').mean():.2f} % (with its bumper "
              f"{100 * vehicle_hazards(train, 'jeep', bumpers=True).mean():.2f} %)")


if __name__ == "__main__":
    main()
