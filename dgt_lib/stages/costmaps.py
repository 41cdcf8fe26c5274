"""Stage ``costmaps``: every method's costmaps of a world, and its occupancy map, cached
(paper: Costmap Inference, Occupancy Map, Baselines).

It joins the trained models (:mod:`dgt_lib.stages.train`), the BEV maps
(:func:`dgt_lib.stages.collect.ensure_bev`) and the dataset (for the slope-based fit)
to the procedures of :mod:`dgt_lib.mapping` (:mod:`~dgt_lib.mapping.costmap`,
:mod:`~dgt_lib.mapping.baselines`, :mod:`~dgt_lib.mapping.occupancy`); the methods are
those of :mod:`dgt_lib.mapping.methods`.

Every costmap is (K, H, W) float32 in [0, 1] on the world's BEV grid (K = 1
for isotropic and binary); layer k is heading θ_k = 2πk/K.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, Profile, as_profile
from dgt_lib.core.geometry import GridSpec
from dgt_lib.mapping.baselines import (
    SlopeModel,
    binary_costmap,
    fit_slope_model,
    forward_slope,
    isotropic_costmap,
    slope_costmap,
)
from dgt_lib.mapping.costmap import directional_costmap
from dgt_lib.mapping.methods import METHODS, check_method
from dgt_lib.mapping.occupancy import (
    TAU_S_ROUTE_CORE_M,
    occupancy_map,
    select_tau_s,
    traversed_gradients,
)
from dgt_lib.mapping.world_maps import WorldMaps
from dgt_lib.perception.bev import BEV_FORMAT, BEVMap
from dgt_lib.perception.dataset import PatchDataset
from dgt_lib.stages.collect import (
    bev_relpath,
    ensure_bev,
    mapped_world_bev,
    warn_if_unobserved,
)
from dgt_lib.stages.dataset import dataset_digest, ensure_dataset
from dgt_lib.stages.output import StageOutput
from dgt_lib.stages.paths import cache_dir, data_dir
from dgt_lib.stages.train import ensure_model, inputs_suffix, model_digest
from dgt_lib.world.mujoco_model import PHYSICS
from dgt_lib.world.terrain import WORLD_NAMES, get_world
from dgt_lib.world.worlds import World

EXPERIMENT_VEHICLES = {"hill": ("carla_cola",), "ridge": ("mercedes_van", "jeep"),
                       "eval": ("jeep", "vw_van")}
"""Vehicles whose costmaps the experiments (and their figures) need, per world."""


def world_bev(world: World | str, profile: Profile | str | None = None, *,
              progress: bool = True) -> tuple[BEVMap, str]:
    """The BEV map of a world and its artifact path in the profile's data directory.

    A name of the kit's worlds goes through :func:`~dgt_lib.stages.collect.ensure_bev`; any other
    :class:`World` (your own terrain, ``worlds.from_heightmap``) is surveyed the same way
    and cached as ``bev/custom/<name>_<hash>.npz`` keyed by its heights, colours and trees;
    when much of it stays unobserved, it warns why
    (:func:`~dgt_lib.stages.collect.warn_if_unobserved`).
    """
    prof = as_profile(profile)
    if isinstance(world, str) or (world.name in WORLD_NAMES
                                  and world is get_world(world.name, prof)):
        name = world if isinstance(world, str) else world.name
        return ensure_bev(name, prof, progress=progress), bev_relpath(name)
    config = {"stage": "bev", "bev_format": BEV_FORMAT, "heights": world.heights,
              "colors": world.colors, "trees": world.trees, "grid": world.grid,
              "collect": prof.collect, "bev_settings": prof.bev, "physics": PHYSICS}
    relpath = f"bev/custom/{world.name}_{artifacts.config_hash(config)[:10]}.npz"
    arrays = artifacts.ensure(relpath, config,
                              lambda: mapped_world_bev(world, prof, progress=progress)[0]
                              .to_arrays(), profile=cache_dir(prof))
    bev = BEVMap.from_arrays(arrays)
    warn_if_unobserved(bev, world, prof.collect)  # built now or cached: say why, every time
    return bev, relpath


def world_key(world: World | str, bev_path: str) -> str:
    """Folder name of a world's costmaps: its name, plus the BEV hash for custom worlds."""
    name = world if isinstance(world, str) else world.name
    return Path(bev_path).stem if bev_path.startswith("bev/custom/") else name


# ----------------------------------------------------------------------------- models
def load_model(profile: Profile | str | None, kind: str = "multitask", *,
               dataset: PatchDataset | None = None, progress: bool = True):
    """The trained ``DGTNet`` of ``kind`` ("multitask" or "single:<vehicle>"), trained first
    (with the dataset, collected first) if the cache does not have it."""
    prof = as_profile(profile)
    dataset = dataset if dataset is not None else ensure_dataset(prof, progress=progress)
    return ensure_model(prof, dataset, kind, progress=progress).model


def ensure_slope_models(profile: Profile | str | None = None, *,
                        dataset_hash: str | None = None,
                        progress: bool = True) -> dict[str, SlopeModel]:
    """The slope-based baseline's {θ0, θmin, θmax, p_u, p_d} per vehicle, fitted with
    Optuna on the training split (cached as ``baselines/slope_models.json``, keyed by the
    dataset's :func:`~dgt_lib.stages.dataset.dataset_fingerprint`, ``dataset_hash`` when
    the caller has it: the dataset is loaded only to fit)."""
    prof = as_profile(profile)
    dataset_hash = dataset_hash or dataset_digest(prof, progress=progress)

    def build() -> dict[str, dict[str, float]]:
        train = ensure_dataset(prof, progress=progress).part("train")
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

    config = {"stage": "slope_models", "dataset": dataset_hash,
              "trials": prof.costmap.slope_trials, "seed": prof.seed}
    fitted = artifacts.ensure("baselines/slope_models.json", config, build,
                              profile=cache_dir(prof))
    return {name: SlopeModel(**params) for name, params in fitted.items()}


def ensure_tau_s(profile: Profile | str | None = None) -> float:
    """τ_s by the paper's rule — the smallest threshold that eliminates no terrain
    traversable in at least one direction — applied to the known-traversable
    routes of the hill and ridge worlds (cached as ``occupancy/tau_s.json``)."""
    prof = as_profile(profile)
    config: dict[str, object] = {"stage": "tau_s", "margin": prof.costmap.tau_s_margin,
                                 "core_m": TAU_S_ROUTE_CORE_M}
    for name in ("hill", "ridge"):
        ensure_bev(name, prof)
        config[name] = artifacts.stored_digest(bev_relpath(name), profile=cache_dir(prof))

    def build() -> dict[str, float]:
        samples = np.concatenate([traversed_gradients(get_world(n, prof), ensure_bev(n, prof))
                                  for n in ("hill", "ridge")])
        return {"tau_s": select_tau_s(samples, prof.costmap.tau_s_margin),
                "steepest_traversed": float(np.nanmax(samples)), "cells": int(samples.size)}

    return float(artifacts.ensure("occupancy/tau_s.json", config, build,
                                  profile=cache_dir(prof))["tau_s"])


def world_occupancy(world: World | str, profile: Profile | str | None = None, *,
                    progress: bool = True) -> tuple[np.ndarray, GridSpec]:
    """The occupancy map (H, W) uint8 of a world's BEV with the profile's τ_s, and its grid:
    what :func:`ensure_world_costmaps` gives the planner, without a dataset or a model
    (the BEV maps only; the training world's needs its episodes)."""
    prof = as_profile(profile)
    bev, _ = world_bev(world, prof, progress=progress)
    return occupancy_map(bev, ensure_tau_s(prof)), bev.grid


INFERENCE_FIELDS: tuple[str, ...] = ("n_headings", "stride")
"""The :class:`CostmapConfig` fields a stored costmap depends on (its cache key, with its
source). Not ``batch_size`` (patches per call: the same costmap up to float rounding), nor
``slope_trials`` (the slope fit, which keys the slope map through its own digest), nor
``tau_s_margin`` (the occupancy map, not stored with the costmaps)."""


COSTMAP_FORMAT = 1
"""The version of a stored costmap: bumped by any change that alters the costs."""


def costmap_config(prof: Profile, bev_path: str, method: str, source: str) -> dict:
    """The cache key of a stored costmap: the BEV map, the method, its ``source`` (the
    model's or the slope fit's digest) and the :data:`INFERENCE_FIELDS`."""
    return {"stage": "costmap", "format": COSTMAP_FORMAT, "bev_path": bev_path,
            "method": method, "source": source,
            "bev": artifacts.stored_digest(bev_path, profile=cache_dir(prof)),
            "costmap": {f: getattr(prof.costmap, f) for f in INFERENCE_FIELDS}}


def _slope_costmaps(prof: Profile, bev: BEVMap, bev_path: str, key: str,
                    ds_hash: str | None, kwargs: dict) -> dict[str, np.ndarray]:
    """The slope baseline's costmaps of every vehicle on a world (one cached file)."""
    slope_models = ensure_slope_models(prof, dataset_hash=ds_hash, progress=kwargs["progress"])
    config = costmap_config(prof, bev_path, "slope",
                             artifacts.stored_digest("baselines/slope_models.json",
                                                     profile=cache_dir(prof)))

    def build_slope() -> dict[str, np.ndarray]:
        cost = slope_costmap(bev, [slope_models[v] for v in VEHICLES],
                             prof.costmap.n_headings, **kwargs)
        return {name: cost[i] for i, name in enumerate(VEHICLES)}

    return artifacts.ensure(f"costmaps/{key}/slope.npz", config, build_slope,
                            profile=cache_dir(prof))


def ensure_world_costmaps(world: World | str, vehicles: tuple[str, ...] | None = None,
                          profile: Profile | str | None = None, *,
                          methods: tuple[str, ...] = METHODS,
                          progress: bool = True) -> WorldMaps:
    """The costmaps of ``methods`` for ``vehicles`` (default: the experiment's) on a world
    (a name of the kit's worlds, or any :class:`World`, e.g. your own terrain). Cached
    under ``costmaps/<world>/``: the multi-task (``dgt``) and slope maps of all four
    vehicles in one file each, one file per single-task model (``dgt_geometry.npz`` …
    for ``train.inputs=geometry``); isotropic and binary are derived on the fly."""
    prof = as_profile(profile)
    world_name = world if isinstance(world, str) else world.name
    vehicles = tuple(vehicles or EXPERIMENT_VEHICLES.get(world_name, VEHICLES))
    for m in methods:
        for v in vehicles:
            check_method(m, v)
    bev, bev_path = world_bev(world, prof, progress=progress)
    key = world_key(world, bev_path)
    # the dataset's fingerprint keys every model and the slope fit; its patches are loaded
    # only to train or fit (a cached map's keys are checked without them)
    ds_hash = (dataset_digest(prof, progress=progress)
               if {"dgt", "isotropic", "single-task", "slope"} & set(methods) else None)
    kwargs = {"stride": prof.costmap.stride, "batch_size": prof.costmap.batch_size,
              "progress": progress}
    k = prof.costmap.n_headings
    sfx = inputs_suffix(prof.train.inputs)  # a geometry model's maps beside the RGB-D one's
    maps: dict[tuple[str, str], np.ndarray] = {}

    @functools.cache
    def dataset() -> PatchDataset:
        return ensure_dataset(prof, progress=progress)

    def model_costmap(kind: str) -> tuple[np.ndarray, tuple[str, ...]]:
        """Model ``kind``'s (n_heads, K, H, W) costmap of this world, and its heads'
        vehicles: the model is loaded (torch imported) only to build a costmap."""
        from dgt_lib.learning.training import window_predictor

        model = ensure_model(prof, dataset(), kind, dataset_hash=ds_hash,
                             progress=progress).model
        cost = directional_costmap(bev, window_predictor(model, prof.costmap.batch_size),
                                   k, **kwargs)
        return cost, model.vehicles

    if {"dgt", "isotropic"} & set(methods):
        config = costmap_config(prof, bev_path, "dgt",
                                 model_digest(prof, None, "multitask", dataset_hash=ds_hash,
                                              progress=progress))

        def build_dgt() -> dict[str, np.ndarray]:
            cost, heads = model_costmap("multitask")
            return dict(zip(heads, cost, strict=True))

        dgt = artifacts.ensure(f"costmaps/{key}/dgt{sfx}.npz", config, build_dgt,
                               profile=cache_dir(prof))
        for v in vehicles:
            if "dgt" in methods:
                maps[("dgt", v)] = dgt[v]
            if "isotropic" in methods:
                maps[("isotropic", v)] = isotropic_costmap(dgt[v])
    if "single-task" in methods:
        for v in vehicles:
            kind = f"single:{v}"
            config = costmap_config(prof, bev_path, kind,
                                     model_digest(prof, None, kind, dataset_hash=ds_hash,
                                                  progress=progress))

            def build_st(kind=kind) -> dict[str, np.ndarray]:
                return {"cost": model_costmap(kind)[0][0]}

            maps[("single-task", v)] = artifacts.ensure(
                f"costmaps/{key}/single_{v}{sfx}.npz", config, build_st,
                profile=cache_dir(prof))["cost"]
    if "slope" in methods:
        slope = _slope_costmaps(prof, bev, bev_path, key, ds_hash, kwargs)
        for v in vehicles:
            maps[("slope", v)] = slope[v]
    if "binary" in methods:
        for v in vehicles:
            maps[("binary", v)] = binary_costmap(bev.grid.shape)
    tau_s = ensure_tau_s(prof)
    return WorldMaps(world_name, bev, occupancy_map(bev, tau_s), tau_s, maps)


def stage_costmaps(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: every method's costmaps on the hill, ridge and eval worlds."""
    prof = as_profile(profile)
    paths, parts = [], []
    for world_name in ("hill", "ridge", "eval"):
        maps = ensure_world_costmaps(world_name, profile=prof)
        paths.append(data_dir(prof) / "costmaps" / world_name)
        occupied = float(np.mean(maps.occupancy == 1))
        parts.append(f"{world_name}: {len(maps.costmaps)} maps, {occupied:.1%} occupied")
    tau = ensure_tau_s(prof)
    return StageOutput(paths, f"τ_s = {tau:.3f} m/m; " + "; ".join(parts))
