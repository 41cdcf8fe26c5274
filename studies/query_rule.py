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

    .venv/bin/python studies/query_rule.py [--profile P ...] [--candidates N] [--publish]

``--publish`` writes the record whose table docs/worlds.md quotes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from runner import Study

from dgt_lib.core.config import get_profile
from dgt_lib.evaluation.experiments import EXPERIMENTS
from dgt_lib.evaluation.hazards import HazardMap, hazard_map, vehicle_hazards
from dgt_lib.records.study import table
from dgt_lib.world.terrain import get_world


@dataclass(frozen=True)
class LineStats:
    """What Experiment 3's query rule sees on a world, from straight lines drawn as
    :func:`~dgt_lib.evaluation.queries.draw_random_queries` draws candidates (footprints
    and feasibility not checked): ``lengths`` (N,) metres of each on-map candidate's line
    on the rule's hazard cells, ``kept`` (N,) whether the rule keeps it, ``crosses`` (N,)
    whether it crosses a cell of ``mask`` (any hazard map given, e.g. one vehicle's)."""

    lengths: np.ndarray
    kept: np.ndarray
    crosses: np.ndarray

    @property
    def kept_crossing(self) -> float:
        """Share of the kept lines that cross a cell of the given mask."""
        return float(self.crosses[self.kept].mean()) if self.kept.any() else float("nan")


def line_stats(rule: HazardMap, mask: HazardMap, distance_m: tuple[float, float],
               min_hazard_m: float, seed: int, candidates: int = 5000,
               margin_m: float = 10.0) -> LineStats:
    """:class:`LineStats` of ``candidates`` lines: start uniform ``margin_m`` inside the
    map, a distance uniform in ``distance_m``, a uniform direction, the goal ``margin_m``
    inside the map (others dropped); kept when ``rule`` finds ≥ ``min_hazard_m`` on it."""
    rng = np.random.default_rng(seed)
    x0, x1, y0, y1 = rule.grid.extent
    rows = []
    for _ in range(candidates):
        sx, sy = rng.uniform(x0 + margin_m, x1 - margin_m), rng.uniform(y0 + margin_m,
                                                                         y1 - margin_m)
        ang, dist = rng.uniform(0, 2 * np.pi), rng.uniform(*distance_m)
        gx, gy = sx + dist * np.cos(ang), sy + dist * np.sin(ang)
        if x0 + margin_m < gx < x1 - margin_m and y0 + margin_m < gy < y1 - margin_m:
            rows.append((rule.length_m((sx, sy), (gx, gy)),
                         mask.length_m((sx, sy), (gx, gy)) > 0.0))
    lengths = np.array([r[0] for r in rows], float)
    return LineStats(lengths, lengths >= min_hazard_m, np.array([r[1] for r in rows], bool))


def pct(x: float) -> str:
    return f"{100 * x:.2f} %"


def main() -> None:
    study = Study("query_rule", __doc__, per_seed=False, several_profiles=True)
    study.parser.add_argument("--candidates", type=int, default=5000)
    args = study.parse()
    _, vehicles, _ = EXPERIMENTS["experiment3"]
    rows = []
    for name in args.profile:
        prof = get_profile(name)
        ex = prof.experiments
        for world_name in ("eval", "eval_hazard"):
            world = get_world(world_name, prof)
            hz = hazard_map(world, vehicles)
            jeep = HazardMap(world.grid, vehicle_hazards(world, "jeep", bumpers=True))
            st = line_stats(hz, jeep, ex.eval_distance_m, ex.eval_min_hazard_m, prof.seed,
                            args.candidates)
            rows.append([name, world_name, f"{world.grid.extent[1]:.0f} m",
                         *(pct(vehicle_hazards(world, v).mean()) for v in vehicles),
                         pct(jeep.fraction), pct(hz.fraction),
                         f"{100 * st.kept.mean():.0f} % of {len(st.lengths)}",
                         f"{np.median(st.lengths):.1f} m", f"{100 * st.kept_crossing:.0f} %"])
        train = get_world("training", prof)
        rows.append([name, "training", f"{train.grid.extent[1]:.0f} m",
                     *("–" if v != "jeep" else pct(vehicle_hazards(train, v).mean())
                       for v in vehicles),
                     pct(vehicle_hazards(train, "jeep", bumpers=True).mean()),
                     "–", "–", "–", "–"])
    columns = ["profile", "world", "side", *(f"{v} hazard cells" for v in vehicles),
               "jeep with its bumper", "hazard cells (either vehicle)",
               "on-map candidates kept by the rule", "median hazard on a candidate line",
               "kept lines crossing a jeep hazard"]
    title = f"Experiment 3's query rule, {args.candidates} candidate lines a world"
    study.finish({"hazards": table(title, columns, rows)}, seeds=[])


if __name__ == "__main__":
    main()
