"""Zero-shot: a costmap for a vehicle that was never driven, scored against its measured
ground truth (docs/vehicles.md → Zero-shot).

Each named vehicle is left out of the conditioned network's training in turn
(:func:`~dgt_lib.stages.conditioned.ensure_conditioned_model`) and its costmap predicted
from its spec alone. On every world whose experiments use that vehicle
(:data:`~dgt_lib.stages.costmaps.EXPERIMENT_VEHICLES`) the map is scored as the kit scores
every method (:func:`~dgt_lib.stages.ground_truth.score_costmap`), beside the maps a
vehicle never driven could otherwise get, and its own:

* ``zero-shot``: the conditioned network trained without it, for its spec;
* ``conditioned seen``: the conditioned network trained on all four vehicles, this one
  included (the network ``dgt plan --vehicle FILE.toml`` plans with): what leaving the
  vehicle out costs;
* ``own head``: its own head of the multi-task model (method ``dgt``: it was driven);
* ``nearest head``: the multi-task head of the seen vehicle nearest in normalised spec
  (:func:`nearest_vehicle`; that model saw the left-out
  vehicle's data too, through the shared backbone);
* ``nearest conditioned``: the network trained without it, for the nearest vehicle's spec;
* ``slope climb``: Slope-Based from its torque-limited climb alone, nothing fitted
  (:func:`~dgt_lib.mapping.baselines.climb_slope_model`).

Where the vehicle is Experiment 1's or 2's, every map also plans the experiment's queries
(``planned.planned_routes``: planned, not driven). The same predictors
are also scored on the vehicle's test patches against their labels (:func:`patch_scores`):
many more samples than the ground truth's cells, of the training world's terrain.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from planned import PLANNED, planned_routes, planning_profile

from dgt_lib.beyond.conditioned import spec_statistics, spec_vector
from dgt_lib.core.config import VEHICLES, Profile, as_profile
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.mapping.baselines import SlopePredictor, climb_slope_model, slope_costmap
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.stages.conditioned import (
    conditioned_heads,
    ensure_conditioned_costmaps,
    ensure_conditioned_model,
    seen_vehicles,
)
from dgt_lib.stages.costmaps import EXPERIMENT_VEHICLES, ensure_world_costmaps
from dgt_lib.stages.dataset import ensure_dataset
from dgt_lib.stages.ground_truth import GROUND_TRUTH_WORLDS, ensure_ground_truths, score_costmap
from dgt_lib.stages.train import ensure_model

ZERO_SHOT_METHODS: tuple[str, ...] = ("zero-shot", "conditioned seen", "own head",
                                      "nearest head", "nearest conditioned", "slope climb")
"""The maps compared for a left-out vehicle (module docstring), in table order."""


def nearest_vehicle(spec: VehicleSpec | str, candidates: Sequence[VehicleSpec | str]
                    ) -> tuple[str, float]:
    """The candidate nearest to ``spec`` and its distance: Euclidean between spec vectors
    normalised by the candidates' :func:`spec_statistics` (the space a network trained on
    them conditions in). The vehicle itself is skipped when among the candidates."""
    v = get_vehicle(spec)
    others = [get_vehicle(c) for c in candidates if get_vehicle(c).name != v.name]
    if not others:
        raise ValueError(f"no candidate other than {v.name}")
    mean, std = spec_statistics(others)
    c = (spec_vector(v) - mean) / std
    dist = [float(np.linalg.norm((spec_vector(o) - mean) / std - c)) for o in others]
    best = int(np.argmin(dist))
    return others[best].name, dist[best]


def scored_worlds(vehicle: str) -> tuple[str, ...]:
    """The ground-truth worlds whose experiments use ``vehicle``."""
    return tuple(w for w in GROUND_TRUTH_WORLDS if vehicle in EXPERIMENT_VEHICLES[w])


def zero_shot_costmaps(world: str, vehicle: str, profile: Profile | str | None = None, *,
                       progress: bool = True) -> tuple[WorldMaps, dict[str, np.ndarray], str]:
    """The world's maps (occupancy, grid), every :data:`ZERO_SHOT_METHODS` costmap of
    ``vehicle`` (K, H, W) left out of the conditioned network, and the nearest seen
    vehicle's name; built through the cache (the slope map is computed: no fit)."""
    prof = as_profile(profile)
    nearest, _ = nearest_vehicle(vehicle, seen_vehicles(vehicle))
    cond = ensure_conditioned_costmaps(world, (vehicle, nearest), prof, leave_out=vehicle,
                                       progress=progress)
    seen = ensure_conditioned_costmaps(world, VEHICLES, prof, progress=progress)
    maps = ensure_world_costmaps(world, (vehicle, nearest), prof, methods=("dgt",),
                                 progress=progress)
    slope = slope_costmap(maps.bev, [climb_slope_model(get_vehicle(vehicle).max_climb_deg)],
                          prof.costmap.n_headings, stride=prof.costmap.stride,
                          batch_size=prof.costmap.batch_size, progress=progress)[0]
    costs = {"zero-shot": cond[vehicle], "conditioned seen": seen[vehicle],
             "own head": maps.costmap("dgt", vehicle),
             "nearest head": maps.costmap("dgt", nearest), "nearest conditioned": cond[nearest],
             "slope climb": slope}
    return maps, costs, nearest


def patch_scores(vehicle: str, profile: Profile | str | None = None, *,
                 progress: bool = True) -> dict[str, dict[str, float]]:
    """{method: :func:`~dgt_lib.learning.training.regression_metrics`} of each
    :data:`ZERO_SHOT_METHODS` predictor of ``vehicle`` on its test-split patches against
    their labels L (the network trained without the vehicle never saw any of its
    patches)."""
    from dgt_lib.learning.training import predict, regression_metrics  # torch: only here

    prof = as_profile(profile)
    nearest, _ = nearest_vehicle(vehicle, seen_vehicles(vehicle))
    dataset = ensure_dataset(prof, progress=progress)
    test = dataset.part("test", vehicle)
    batch = prof.costmap.batch_size
    net = ensure_conditioned_model(prof, dataset, vehicle, progress=progress).model
    conditioned = predict(net.for_vehicles([vehicle, nearest]), test.patches, batch)
    seen = ensure_conditioned_model(prof, dataset, None, progress=progress).model
    seen_head = predict(seen, test.patches, batch)[:, seen.head_index(vehicle)]
    multi = ensure_model(prof, dataset, "multitask", progress=progress).model
    heads = predict(multi, test.patches, batch)
    slope = SlopePredictor([climb_slope_model(get_vehicle(vehicle).max_climb_deg)])
    preds = {"zero-shot": conditioned[:, 0], "conditioned seen": seen_head,
             "own head": heads[:, multi.head_index(vehicle)],
             "nearest head": heads[:, multi.head_index(nearest)],
             "nearest conditioned": conditioned[:, 1], "slope climb": slope(test.patches)[:, 0]}
    return {m: regression_metrics(preds[m], test.labels) for m in ZERO_SHOT_METHODS}


def zero_shot_scores(vehicle: str, profile: Profile | str | None = None, *,
                     plans: bool = True, progress: bool = True) -> dict:
    """One left-out vehicle in the profile's run seed: ``rows`` (world, vehicle, method,
    excluded and :func:`~dgt_lib.evaluation.accuracy.costmap_accuracy`'s scores) per
    scored world and :data:`ZERO_SHOT_METHODS`, the ``nearest`` vehicle and its spec
    ``distance``, the number of ``generated`` training vehicles and of those
    ``generated_used`` without this one (near copies skipped), the :func:`patch_scores`
    as ``patches``, and with ``plans`` the ``planned.PLANNED``
    experiments of this vehicle as
    ``{experiment: {method: {label: {route: n}}}}``."""
    prof = as_profile(profile)
    if vehicle not in VEHICLES:
        raise ValueError(f"unknown vehicle {vehicle!r}; valid: {', '.join(VEHICLES)}")
    worlds = scored_worlds(vehicle)
    truths = ensure_ground_truths([(w, vehicle) for w in worlds], prof, progress=progress)
    nearest, distance = nearest_vehicle(vehicle, seen_vehicles(vehicle))
    rows, routes = [], {}
    for w in worlds:
        maps, costs, _ = zero_shot_costmaps(w, vehicle, prof, progress=progress)
        for method, cost in costs.items():
            scores, _ = score_costmap(cost, truths[(w, vehicle)], maps, prof)
            rows.append({"world": w, "vehicle": vehicle, "method": method, **scores})
        for name, (world, planned_vehicle, _) in PLANNED.items():
            if plans and (world, planned_vehicle) == (w, vehicle):
                routes[name] = {m: planned_routes(name, planning_profile(prof), cost)
                                for m, cost in costs.items()}
    n_seen = len(seen_vehicles(vehicle))
    return {"vehicle": vehicle, "seed": prof.seed, "nearest": nearest, "distance": distance,
            "generated": prof.conditioned.generated_vehicles,
            "generated_used": len(conditioned_heads(prof, vehicle)) - n_seen,
            "rows": rows, "patches": patch_scores(vehicle, prof, progress=progress),
            "plans": routes}
