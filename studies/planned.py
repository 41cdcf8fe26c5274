"""Experiments 1 and 2 planned only, not driven: which route each query's Hybrid A* plan
takes on a costmap (the paper's claims, ascents by Route A and descents by Route B on the
hill, crossings at the smoothed section of the ridge). What the studies compare maps by
when closed-loop trials would cost too much (``map_inputs.py``, ``zero_shot.py``).
"""

from __future__ import annotations

import numpy as np

from dgt_lib.core.config import Profile
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.evaluation.experiments import experiment_queries
from dgt_lib.evaluation.queries import classify_route
from dgt_lib.navigation.planner.hybrid_astar import HybridAStar
from dgt_lib.stages.experiments import trial_maps
from dgt_lib.world.terrain import get_world

PLANNED = {"experiment1": ("hill", "carla_cola", 20), "experiment2": ("ridge", "mercedes_van", 50)}
"""Experiments whose plans are scored: world, vehicle, queries (the paper's n)."""
CLAIMS = (("experiment1", "ascent", "A"), ("experiment1", "descent", "B"),
          ("experiment2", None, "smooth"))
"""The paper's plan claims: (experiment, query label or None for all, route)."""


def planning_profile(prof: Profile) -> Profile:
    """``prof`` with the paper's number of queries of each :data:`PLANNED` experiment."""
    return prof.with_overrides({f"experiments.n_{w}": n for w, _, n in PLANNED.values()})


def planned_routes(name: str, prof: Profile, costmap: np.ndarray | None = None
                   ) -> dict[str, dict[str, int]]:
    """{query label: {route: plans}} of experiment ``name``'s queries (at ``prof``'s n and
    seed) planned for its vehicle on ``costmap`` (K, H, W) on the world's BEV grid —
    default the ``dgt`` costmap — with the world's occupancy map."""
    world_name, vehicle, _ = PLANNED[name]
    world = get_world(world_name, prof)
    queries = experiment_queries(name, prof, trial_maps)[vehicle]
    maps = trial_maps(world_name, "dgt" if costmap is None else "binary", vehicle, prof)
    cost = maps.costmap("dgt", vehicle) if costmap is None else costmap
    planner = HybridAStar.for_vehicle(cost, maps.occupancy, maps.grid, get_vehicle(vehicle),
                                      prof.planner)
    routes: dict[str, dict[str, int]] = {}
    for q in queries:
        plan = planner.plan(q.start, q.goal)
        route = classify_route(world, plan.path) if plan.success else "no path"
        label = routes.setdefault(q.label or "all", {})
        label[route] = label.get(route, 0) + 1
    return routes


def claim_share(routes: dict[str, dict[str, int]], label: str | None, route: str
                ) -> tuple[int, int]:
    """(plans by ``route``, plans) among the queries labelled ``label`` (None: all)."""
    labels = [label] if label else list(routes)
    return (sum(routes.get(lab, {}).get(route, 0) for lab in labels),
            sum(sum(routes.get(lab, {}).values()) for lab in labels))
