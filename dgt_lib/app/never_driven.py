"""A vehicle that was never driven, for ``dgt plan --vehicle FILE.toml``
(:func:`plan_vehicle_query`): its spec read and checked before any work, and its costmap
from the vehicle-conditioned network trained on the four named vehicles
(docs/vehicles.md). It stays apart from :mod:`dgt_lib.app.plan_one`, which plans the named
vehicles with the paper's methods alone, and hands it a
:class:`~dgt_lib.app.query.CostmapSource`.

A name of a named vehicle, or a file that holds exactly a named vehicle's spec, plans as
before with that vehicle's own maps. Any other spec has no head of its own: ``dgt`` maps
come from :func:`~dgt_lib.stages.conditioned.ensure_conditioned_costmaps` (``isotropic``
is their mean), ``slope`` is Slope-Based from its torque-limited climb
(:func:`~dgt_lib.mapping.baselines.climb_slope_model`, nothing fitted), ``binary`` the
occupancy alone; ``single-task`` has no model for it.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from dgt_lib.app import plan_one
from dgt_lib.app.query import CostmapSource, QueryReport
from dgt_lib.core.config import Profile, as_profile
from dgt_lib.core.vehicle_range import VehicleRangeWarning, resolve_vehicle
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.core.vehicles import is_named
from dgt_lib.mapping.baselines import (
    binary_costmap,
    climb_slope_model,
    isotropic_costmap,
    slope_costmap,
)
from dgt_lib.mapping.occupancy import occupancy_map
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.stages.conditioned import (
    conditioned_relpath,
    ensure_conditioned_costmaps,
    seen_vehicles,
)
from dgt_lib.stages.costmaps import ensure_tau_s, world_bev
from dgt_lib.stages.paths import data_dir
from dgt_lib.world.worlds import World

NEVER_DRIVEN_METHODS: tuple[str, ...] = ("dgt", "isotropic", "slope", "binary")
"""The methods that have a costmap for a vehicle never driven."""


def range_warnings(vehicle: str | Path | VehicleSpec) -> tuple[VehicleSpec, list[str]]:
    """:func:`~dgt_lib.core.vehicle_range.resolve_vehicle`, with its range warnings'
    messages collected (not shown)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", VehicleRangeWarning)
        spec = resolve_vehicle(vehicle)
    return spec, [str(w.message) for w in caught if issubclass(w.category, VehicleRangeWarning)]


def check_method_for(method: str, spec: VehicleSpec) -> None:
    """ValueError when ``method`` has no costmap for a vehicle never driven."""
    if method not in NEVER_DRIVEN_METHODS:
        raise ValueError(f"{spec.name} was never driven: it has no {method} model; methods "
                         f"for it: {', '.join(NEVER_DRIVEN_METHODS)}")


def never_driven_notice(method: str, spec: VehicleSpec, profile: Profile, *,
                        training: bool = True) -> str:
    """The line saying where a never-driven vehicle's costmap comes from (with
    ``training``: and that the conditioned network is trained first when the profile has
    none yet)."""
    if method == "binary":
        return f"{spec.name} was never driven: binary plans on the occupancy map alone"
    if method == "slope":
        return (f"{spec.name} was never driven: Slope-Based costmap from its torque-limited "
                f"climb {spec.max_climb_deg:.1f}° alone (nothing fitted)")
    line = (f"never driven: costmap from the vehicle-conditioned network trained on "
            f"{', '.join(seen_vehicles(None))} (profile {profile.name}, seed {profile.seed}), "
            f"given {spec.name}'s spec")
    model = conditioned_relpath(None, profile.conditioned.generated_vehicles,
                                profile.train.inputs)
    if training and not (data_dir(profile) / model).exists():
        line += "; training it first on the profile's dataset (later queries reuse it)"
    return line


def never_driven_maps(world: World, spec: VehicleSpec, method: str, profile: Profile, *,
                      progress: bool = True) -> tuple[WorldMaps, np.ndarray]:
    """The world's maps (BEV, occupancy, τ_s) and ``method``'s costmap (K, H, W) of a
    vehicle never driven (module docstring)."""
    check_method_for(method, spec)
    bev, _ = world_bev(world, profile, progress=progress)
    tau_s = ensure_tau_s(profile)
    maps = WorldMaps(world.name, bev, occupancy_map(bev, tau_s), tau_s, {})
    if method == "binary":
        return maps, binary_costmap(bev.grid.shape)
    c = profile.costmap
    if method == "slope":
        return maps, slope_costmap(bev, [climb_slope_model(spec.max_climb_deg)], c.n_headings,
                                   stride=c.stride, batch_size=c.batch_size,
                                   progress=progress)[0]
    cost = ensure_conditioned_costmaps(world, (spec,), profile, progress=progress)[spec.name]
    return maps, isotropic_costmap(cost) if method == "isotropic" else cost


def plan_vehicle_query(world: str | World, vehicle: str | Path | VehicleSpec, start, goal, *,
                       method: str = "dgt", profile: Profile | str | None = None,
                       progress: bool = True, **query: Any) -> QueryReport:
    """:func:`~dgt_lib.app.plan_one.plan_query` for a named vehicle, a vehicle file or a spec
    (``dgt plan --vehicle``): an impossible spec, or a method without a map for a vehicle
    never driven, is a ValueError before any work; each field outside the training
    vehicles' range is a warning (printed with ``progress``, and in the report); a vehicle
    never driven plans on :func:`never_driven_maps`, saying where they come from.
    ``query``: the rest of plan_query's options (drive, out_dir, …)."""
    prof = plan_one.costmap_profile(world, method, as_profile(profile), query.get("image"))[0]
    spec, notes = range_warnings(vehicle)
    for note in notes if progress else ():
        print(f"warning: {note}", file=sys.stderr, flush=True)
    source = None
    if not is_named(spec):
        check_method_for(method, spec)
        source = CostmapSource(
            lambda w: never_driven_maps(w, spec, method, prof, progress=progress),
            never_driven_notice(method, spec, prof),
            never_driven_notice(method, spec, prof, training=False), notes)
    report = plan_one.plan_query(world, spec, start, goal, method=method, profile=profile,
                                 progress=progress, source=source, **query)
    report.warnings = notes
    return report
