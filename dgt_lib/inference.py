"""Costmaps of every method for a world, and its occupancy map, through the cache.

This is the ``costmaps`` stage: it joins the trained models (``dgt_lib.train``),
the BEV maps (``dgt_lib.collect.ensure_bev``) and the dataset (for the
slope-based fit) to the costmap procedures of ``dgt_lib.costmap`` and
``dgt_lib.baselines``. The methods are the paper's (Section Baselines):

=============  ===============================================================
``dgt``         DGT-Map: directional costmap of the multi-task model
``isotropic``   DGT-Map(Iso): mean of the ``dgt`` layers, one layer
``single-task``  DGT-Map(ST): directional costmap of the vehicle's single-task model
``slope``       Slope-based: L_sb of the plane-fit forward slope, fitted with Optuna
``binary``      Binary: zero cost, occupancy only
=============  ===============================================================

Every costmap is (K, H, W) float32 in [0, 1] on the world's BEV grid (K = 1
for isotropic and binary); layer k is heading θ_k = 2πk/K.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import artifacts
from .baselines import (
    SlopeModel,
    binary_costmap,
    fit_slope_model,
    forward_slope,
    isotropic_costmap,
    slope_costmap,
)
from .bev import GRADIENT, BEVMap
from .collect import bev_relpath, ensure_bev
from .config import VEHICLES, Profile, get_profile
from .costmap import directional_costmap, occupancy_map, select_tau_s
from .dataset import PatchDataset, ensure_dataset
from .geometry import GridSpec
from .pipeline import StageOutput
from .worlds import WORLD_NAMES, World, get_world, polyline_distance

METHODS: tuple[str, ...] = ("dgt", "isotropic", "single-task", "slope", "binary")
"""The compared methods, in the order of the paper's Table I."""
METHOD_LABELS = {"dgt": "DGT-Map", "isotropic": "DGT-Map(Iso)", "single-task": "DGT-Map(ST)",
                 "slope": "Slope-Based", "binary": "Binary"}
EXPERIMENT_VEHICLES = {"hill": ("carla_cola",), "ridge": ("mercedes_van", "jeep"),
                       "eval": ("jeep", "vw_van")}
"""Vehicles whose costmaps the experiments (and their figures) need, per world."""
TAU_S_ROUTE_CORE_M = 1.5
"""Cells within this distance of a known-traversable route's centre line define τ_s [m]."""


def _profile(profile: Profile | str | None) -> Profile:
    return profile if isinstance(profile, Profile) else get_profile(profile)


def world_bev(world: World | str, profile: Profile | str | None = None, *,
              progress: bool = True) -> tuple[BEVMap, str]:
    """The BEV map of a world and its artifact path under ``data/<profile>/``.

    A name of the kit's worlds goes through :func:`dgt_lib.collect.ensure_bev`; any other
    :class:`World` (your own terrain, ``worlds.from_heightmap``) is surveyed the same way
    and cached as ``bev/custom/<name>_<hash>.npz`` keyed by its heights, colours and trees.
    """
    prof = _profile(profile)
    if isinstance(world, str) or (world.name in WORLD_NAMES
                                  and world is get_world(world.name, prof)):
        name = world if isinstance(world, str) else world.name
        return ensure_bev(name, prof, progress=progress), bev_relpath(name)
    from .collect import build_bev

    config = {"stage": "bev", "heights": world.heights, "colors": world.colors,
              "trees": world.trees, "grid": world.grid, "collect": prof.collect}
    relpath = f"bev/custom/{world.name}_{artifacts.config_hash(config)[:10]}.npz"
    arrays = artifacts.ensure(relpath, config,
                              lambda: build_bev(world, prof.collect, progress=progress)[0]
                              .to_arrays(), profile=prof.name)
    return BEVMap.from_arrays(arrays), relpath


def _world_key(world: World | str, bev_path: str) -> str:
    """Folder name of a world's costmaps: its name, plus the BEV hash for custom worlds."""
    name = world if isinstance(world, str) else world.name
    return Path(bev_path).stem if bev_path.startswith("bev/custom/") else name


def _check(method: str, vehicle: str) -> None:
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; valid methods: {', '.join(METHODS)}")
    if vehicle not in VEHICLES:
        raise ValueError(f"unknown vehicle {vehicle!r}; valid vehicles: {', '.join(VEHICLES)}")


# ----------------------------------------------------------------------------- models
def load_model(profile: Profile | str | None, kind: str = "multitask", *,
               dataset: PatchDataset | None = None, progress: bool = True):
    """The trained ``DGTNet`` of ``kind`` ("multitask" or "single:<vehicle>"), trained first
    (with the dataset, collected first) if the cache does not have it."""
    from .train import ensure_model

    prof = _profile(profile)
    dataset = dataset if dataset is not None else ensure_dataset(prof, progress=progress)
    return ensure_model(prof, dataset, kind, progress=progress).model


def _model_fingerprint(profile: Profile, kind: str) -> str:
    from .train import model_relpath

    return artifacts.stored_digest(model_relpath(kind), profile=profile.name)


def ensure_slope_models(profile: Profile | str | None = None, *,
                        dataset: PatchDataset | None = None,
                        progress: bool = True) -> dict[str, SlopeModel]:
    """The slope-based baseline's {θ0, θmin, θmax, p_u, p_d} per vehicle, fitted with
    Optuna on the training split (cached as ``baselines/slope_models.json``)."""
    prof = _profile(profile)
    ds = dataset if dataset is not None else ensure_dataset(prof, progress=progress)
    train = ds.part("train")

    def build() -> dict[str, dict[str, float]]:
        theta = forward_slope(train.patches, train.observed)
        out = {}
        for v, name in enumerate(VEHICLES):
            sel = train.vehicle == v
            if not sel.any():
                raise ValueError(f"no training patches of {name}: cannot fit its slope model")
            out[name] = fit_slope_model(theta[sel], train.labels[sel],
                                        n_trials=prof.costmap.slope_trials,
                                        seed=prof.seed).to_dict()
        return out

    config = {"stage": "slope_models", "dataset": artifacts.config_hash(ds.to_arrays()),
              "trials": prof.costmap.slope_trials, "seed": prof.seed}
    fitted = artifacts.ensure("baselines/slope_models.json", config, build, profile=prof.name)
    return {name: SlopeModel(**params) for name, params in fitted.items()}


# ----------------------------------------------------------------------------- occupancy
def traversed_gradients(world_name: str, profile: Profile) -> np.ndarray:
    """‖∇H̄‖ of the BEV cells on a world's known-traversable routes (within
    :data:`TAU_S_ROUTE_CORE_M` of the route centre lines): the hill's Routes A and
    B (B is steep but traversable downhill) and the ridge's crossings (the sharp one
    is traversable by the jeep)."""
    world = get_world(world_name, profile)
    bev = ensure_bev(world_name, profile)
    x, y = bev.grid.cell_centers()
    points = np.stack([x[bev.observed], y[bev.observed]], axis=1)
    grads = bev.channels[GRADIENT][bev.observed]
    near = np.zeros(len(points), bool)
    for route in world.routes.values():
        near |= polyline_distance(points, np.asarray(route, float))[0] <= TAU_S_ROUTE_CORE_M
    return grads[near]


def ensure_tau_s(profile: Profile | str | None = None) -> float:
    """τ_s by the paper's rule — the smallest threshold that eliminates no terrain
    traversable in at least one direction — applied to the known-traversable
    routes of the hill and ridge worlds (cached as ``occupancy/tau_s.json``)."""
    prof = _profile(profile)
    config: dict[str, object] = {"stage": "tau_s", "margin": prof.costmap.tau_s_margin,
                                 "core_m": TAU_S_ROUTE_CORE_M}
    for name in ("hill", "ridge"):
        ensure_bev(name, prof)
        config[name] = artifacts.stored_digest(bev_relpath(name), profile=prof.name)

    def build() -> dict[str, float]:
        samples = np.concatenate([traversed_gradients(n, prof) for n in ("hill", "ridge")])
        return {"tau_s": select_tau_s(samples, prof.costmap.tau_s_margin),
                "steepest_traversed": float(np.nanmax(samples)), "cells": int(samples.size)}

    return float(artifacts.ensure("occupancy/tau_s.json", config, build,
                                  profile=prof.name)["tau_s"])


def world_occupancy(world: World | str, profile: Profile | str | None = None
                    ) -> tuple[np.ndarray, GridSpec]:
    """The occupancy map (H, W) uint8 of a world's BEV with the profile's τ_s, and its grid."""
    prof = _profile(profile)
    bev, _ = world_bev(world, prof)
    return occupancy_map(bev, ensure_tau_s(prof)), bev.grid


# ----------------------------------------------------------------------------- costmaps
@dataclass
class WorldMaps:
    """Everything a planner needs on one world: the BEV, occupancy, τ_s and costmaps."""

    world: str
    bev: BEVMap
    occupancy: np.ndarray
    tau_s: float
    costmaps: dict[tuple[str, str], np.ndarray]  # (method, vehicle) → (K, H, W)

    @property
    def grid(self) -> GridSpec:
        return self.bev.grid

    def costmap(self, method: str, vehicle: str) -> np.ndarray:
        _check(method, vehicle)
        if (method, vehicle) not in self.costmaps:
            raise KeyError(f"{method} costmap of {vehicle} was not computed for {self.world}; "
                           f"have: {sorted(self.costmaps)}")
        return self.costmaps[(method, vehicle)]


def _costmap_config(prof: Profile, bev_path: str, method: str, source: str) -> dict:
    return {"stage": "costmap", "bev_path": bev_path, "method": method, "source": source,
            "bev": artifacts.stored_digest(bev_path, profile=prof.name),
            "costmap": prof.costmap}


def ensure_world_costmaps(world: World | str, vehicles: tuple[str, ...] | None = None,
                          profile: Profile | str | None = None, *,
                          methods: tuple[str, ...] = METHODS,
                          progress: bool = True) -> WorldMaps:
    """The costmaps of ``methods`` for ``vehicles`` (default: the experiment's) on a world
    (a name of the kit's worlds, or any :class:`World`, e.g. your own terrain).

    Cached under ``costmaps/<world>/``: the multi-task (``dgt``) and slope maps of
    all four vehicles in one file each (one backbone pass serves every head), one
    file per single-task model. Isotropic and binary are derived on the fly.
    """
    prof = _profile(profile)
    world_name = world if isinstance(world, str) else world.name
    vehicles = tuple(vehicles or EXPERIMENT_VEHICLES.get(world_name, VEHICLES))
    for m in methods:
        for v in vehicles:
            _check(m, v)
    bev, bev_path = world_bev(world, prof, progress=progress)
    key = _world_key(world, bev_path)
    ds = None
    if {"dgt", "isotropic", "single-task", "slope"} & set(methods):
        ds = ensure_dataset(prof, progress=progress)
    kwargs = {"stride": prof.costmap.stride, "batch_size": prof.costmap.batch_size,
              "progress": progress}
    k = prof.costmap.n_headings
    maps: dict[tuple[str, str], np.ndarray] = {}

    if {"dgt", "isotropic"} & set(methods):
        model = load_model(prof, "multitask", dataset=ds, progress=progress)
        config = _costmap_config(prof, bev_path, "dgt", _model_fingerprint(prof, "multitask"))

        def build_dgt() -> dict[str, np.ndarray]:
            from .train import predict

            cost = directional_costmap(bev, lambda p: predict(model, p, prof.costmap.batch_size),
                                       k, **kwargs)
            return {name: cost[model.head_index(name)] for name in model.vehicles}

        dgt = artifacts.ensure(f"costmaps/{key}/dgt.npz", config, build_dgt,
                               profile=prof.name)
        for v in vehicles:
            if "dgt" in methods:
                maps[("dgt", v)] = dgt[v]
            if "isotropic" in methods:
                maps[("isotropic", v)] = isotropic_costmap(dgt[v])
    if "single-task" in methods:
        for v in vehicles:
            kind = f"single:{v}"
            model = load_model(prof, kind, dataset=ds, progress=progress)
            config = _costmap_config(prof, bev_path, kind, _model_fingerprint(prof, kind))

            def build_st(model=model) -> dict[str, np.ndarray]:
                from .train import predict

                cost = directional_costmap(
                    bev, lambda p: predict(model, p, prof.costmap.batch_size), k, **kwargs)
                return {"cost": cost[0]}

            maps[("single-task", v)] = artifacts.ensure(
                f"costmaps/{key}/single_{v}.npz", config, build_st,
                profile=prof.name)["cost"]
    if "slope" in methods:
        slope_models = ensure_slope_models(prof, dataset=ds, progress=progress)
        config = _costmap_config(prof, bev_path, "slope",
                                 artifacts.stored_digest("baselines/slope_models.json",
                                                         profile=prof.name))

        def build_slope() -> dict[str, np.ndarray]:
            cost = slope_costmap(bev, [slope_models[v] for v in VEHICLES], k, **kwargs)
            return {name: cost[i] for i, name in enumerate(VEHICLES)}

        slope = artifacts.ensure(f"costmaps/{key}/slope.npz", config, build_slope,
                                 profile=prof.name)
        for v in vehicles:
            maps[("slope", v)] = slope[v]
    if "binary" in methods:
        for v in vehicles:
            maps[("binary", v)] = binary_costmap(bev.grid.shape)
    tau_s = ensure_tau_s(prof)
    return WorldMaps(world_name, bev, occupancy_map(bev, tau_s), tau_s, maps)


def stage_costmaps(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: every method's costmaps on the hill, ridge and eval worlds."""
    prof = _profile(profile)
    paths, parts = [], []
    for world_name in ("hill", "ridge", "eval"):
        maps = ensure_world_costmaps(world_name, profile=prof)
        paths.append(artifacts.profile_dir(prof.name) / "costmaps" / world_name)
        occupied = float(np.mean(maps.occupancy == 1))
        parts.append(f"{world_name}: {len(maps.costmaps)} maps, {occupied:.1%} occupied")
    tau = ensure_tau_s(prof)
    return StageOutput(paths, f"τ_s = {tau:.3f} m/m; " + "; ".join(parts))
