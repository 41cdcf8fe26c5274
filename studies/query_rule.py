"""How much of each profile's evaluation world Experiment 3's query rule calls hazardous,
and what share of candidate queries it keeps (dgt_lib/evaluation/hazards.py).

No artifacts: the rule reads only the world's true heights and the vehicles' specs. The
candidates are drawn as ``draw_random_queries`` draws them (start 10 m inside the map, a
distance uniform in ``eval_distance_m``, a uniform direction, the goal 10 m inside the map);
footprints and feasibility, which need the mapped occupancy, are not checked here — the
``dgt reproduce`` run's draw reports those (``QueryDraw.rejected``).

    .venv/bin/python studies/query_rule.py [PROFILE ...] [--candidates N]
"""

from __future__ import annotations

import argparse

import numpy as np

from dgt_lib.core.config import PROFILE_NAMES, get_profile
from dgt_lib.evaluation.experiments import EXPERIMENTS
from dgt_lib.evaluation.hazards import hazard_map, vehicle_hazards
from dgt_lib.world.terrain import get_world


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("profiles", nargs="*", default=list(PROFILE_NAMES))
    ap.add_argument("--candidates", type=int, default=5000)
    args = ap.parse_args()
    world_name, vehicles, _ = EXPERIMENTS["experiment3"]
    for name in args.profiles:
        prof = get_profile(name)
        ex, world = prof.experiments, get_world(world_name, prof)
        hz = hazard_map(world, vehicles)
        per_vehicle = ", ".join(f"{v} {100 * vehicle_hazards(world, v).mean():.2f} %"
                                for v in vehicles)
        rng = np.random.default_rng(prof.seed)
        x0, x1, y0, y1 = world.grid.extent
        lengths = []
        for _ in range(args.candidates):
            sx, sy = rng.uniform(x0 + 10, x1 - 10), rng.uniform(y0 + 10, y1 - 10)
            ang, dist = rng.uniform(0, 2 * np.pi), rng.uniform(*ex.eval_distance_m)
            gx, gy = sx + dist * np.cos(ang), sy + dist * np.sin(ang)
            if x0 + 10 < gx < x1 - 10 and y0 + 10 < gy < y1 - 10:
                lengths.append(hz.length_m((sx, sy), (gx, gy)))
        kept = np.mean(np.asarray(lengths) >= ex.eval_min_hazard_m)
        print(f"{name}: eval {world.grid.extent[1]:.0f} m, hazard cells {100 * hz.fraction:.2f} % "
              f"({per_vehicle}); of {len(lengths)} on-map candidates "
              f"({ex.eval_distance_m[0]:.0f}–{ex.eval_distance_m[1]:.0f} m) the rule "
              f"(≥ {ex.eval_min_hazard_m:g} m of hazard) keeps {100 * kept:.0f} %; "
              f"median hazard on the line {np.median(lengths):.1f} m")


if __name__ == "__main__":
    main()
