"""The vehicle-conditioned network through the artifact cache, and its costmaps for any
vehicle (docs/vehicles.md; the network is :mod:`dgt_lib.beyond.conditioned`).

:func:`ensure_conditioned_model` trains a :class:`~dgt_lib.beyond.conditioned.ConditionedNet`
on the named vehicles' data, all four or all but one (``leave_out``: that vehicle is
then predicted from its spec alone), keyed like the multi-task model
(:func:`~dgt_lib.stages.train.model_config`: dataset, training settings, seed, RGB
weights, checkpoint layout) plus what is left out and the FiLM generator's size.
:func:`ensure_conditioned_costmaps` runs the kit's costmap inference
(:func:`~dgt_lib.mapping.costmap.directional_costmap`) with it for any specs on a world.
With ``conditioned.generated_vehicles`` = N > 0 the models also learn from N generated
vehicles (:mod:`dgt_lib.stages.generated`), stored apart as ``models/<stem>_gen<N>.pt``.
Nothing here changes the keys of the multi-task and single-task models or their maps.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, Profile, as_profile
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.learning.checkpoints import TrainResult, checkpoint_dict, prediction_digest
from dgt_lib.mapping.costmap import directional_costmap
from dgt_lib.perception.dataset import PatchDataset
from dgt_lib.stages.costmaps import costmap_config, world_bev, world_key
from dgt_lib.stages.dataset import dataset_digest, ensure_dataset
from dgt_lib.stages.generated import (
    NEAR_COPY_FRACTION,
    combined_dataset,
    ensure_generated_dataset,
    generated_digest,
    profile_generated,
    training_generated,
)
from dgt_lib.stages.paths import cache_dir, data_dir
from dgt_lib.stages.train import (
    SNAPSHOT_EVERY_S,
    inputs_suffix,
    model_config,
    rgb_weights_for,
)
from dgt_lib.world.worlds import World

FILM_HIDDEN = 64
"""Units of the FiLM generator's hidden layer of the cached models."""
CONDITIONED_FORMAT = 1
"""Version of the conditioned model's recipe (part of its cache key)."""


def seen_vehicles(leave_out: str | None) -> tuple[str, ...]:
    """The named vehicles a conditioned model trains on: all four but ``leave_out``."""
    if leave_out is not None and leave_out not in VEHICLES:
        raise ValueError(f"unknown vehicle {leave_out!r} to leave out; valid: "
                         f"{', '.join(VEHICLES)}")
    return tuple(v for v in VEHICLES if v != leave_out)


def conditioned_stem(leave_out: str | None, generated: int = 0, inputs: str = "rgbd") -> str:
    """``conditioned`` (trained on all four) or ``conditioned_without_<vehicle>``, with
    ``_gen<N>`` when N > 0 generated vehicles joined its training and
    :func:`~dgt_lib.stages.train.inputs_suffix` when it reads other ``train.inputs``."""
    seen_vehicles(leave_out)
    stem = "conditioned" if leave_out is None else f"conditioned_without_{leave_out}"
    stem = stem if generated == 0 else f"{stem}_gen{generated}"
    return stem + inputs_suffix(inputs)


def conditioned_relpath(leave_out: str | None, generated: int = 0,
                        inputs: str = "rgbd") -> Path:
    """Where a conditioned model lives in the seed's data directory: ``models/<stem>.pt``."""
    return Path("models") / f"{conditioned_stem(leave_out, generated, inputs)}.pt"


def conditioned_config(profile: Profile, dataset: PatchDataset | None,
                       leave_out: str | None = None, *,
                       dataset_hash: str | None = None) -> dict[str, Any]:
    """The cache key of a conditioned model: the multi-task model's
    (:func:`~dgt_lib.stages.train.model_config`) with its own kind, heads, the vehicle
    left out, the FiLM size and :data:`CONDITIONED_FORMAT`; with generated vehicles
    (``conditioned.generated_vehicles`` > 0 only, so the others keep their keys) their
    number, their dataset's fingerprint and the near-copy rule. Computed without torch."""
    prof = as_profile(profile)
    base = model_config(prof, dataset, "multitask", dataset_hash=dataset_hash)
    config = {**base, "kind": "conditioned", "vehicles": list(seen_vehicles(leave_out)),
              "leave_out": leave_out, "film_hidden": FILM_HIDDEN,
              "conditioned_format": CONDITIONED_FORMAT}
    n = prof.conditioned.generated_vehicles
    if n == 0:
        return config
    return {**config, "generated": {"vehicles": n, "dataset": generated_digest(prof),
                                    "near_copy_fraction": NEAR_COPY_FRACTION}}


def conditioned_heads(profile: Profile, leave_out: str | None) -> list[VehicleSpec]:
    """The heads a conditioned model trains: the named vehicles but ``leave_out``, then
    the generated vehicles it learns from (:func:`~dgt_lib.stages.generated.training_generated`;
    none while ``conditioned.generated_vehicles`` is 0)."""
    named = [get_vehicle(v) for v in seen_vehicles(leave_out)]
    if as_profile(profile).conditioned.generated_vehicles == 0:
        return named
    return named + training_generated(profile, leave_out)


def ensure_conditioned_model(profile: Profile, dataset: PatchDataset,
                             leave_out: str | None = None, *, progress: bool = True,
                             dataset_hash: str | None = None) -> TrainResult:
    """The conditioned model trained without ``leave_out`` (None: on all four vehicles)
    from the cache, trained if needed, as :func:`~dgt_lib.stages.train.ensure_model`
    trains the multi-task model: the same settings, seed, snapshots and resume, the
    same fingerprint rule (its prediction digest)."""
    from dgt_lib.beyond.conditioned import (  # torch
        load_conditioned,
        train_conditioned,
        train_conditioned_specs,
    )
    from dgt_lib.learning.training import resolve_device

    prof = as_profile(profile)
    device = resolve_device(prof.execution.device)
    config = conditioned_config(prof, dataset, leave_out, dataset_hash=dataset_hash)
    n_generated = prof.conditioned.generated_vehicles
    relpath = conditioned_relpath(leave_out, n_generated, prof.train.inputs)
    snapshot = data_dir(prof) / relpath.with_suffix(".resume.pt")
    heads = conditioned_heads(prof, leave_out)
    run = {"seed": prof.seed, "film_hidden": FILM_HIDDEN, "device": device,
           "progress": progress, "rgb_weights": rgb_weights_for(prof.train),
           "keep_best_on_interrupt": False,
           "snapshot_path": snapshot, "snapshot_key": config,
           "snapshot_every_s": SNAPSHOT_EVERY_S}

    def build() -> dict[str, Any]:
        if n_generated == 0:
            return checkpoint_dict(train_conditioned(
                dataset, prof.train, vehicles=seen_vehicles(leave_out), **run))
        seen = seen_vehicles(leave_out)
        data = combined_dataset(dataset, seen, ensure_generated_dataset(prof, progress=progress),
                                [s.name for s in profile_generated(prof)],
                                [s.name for s in heads[len(seen):]])
        return checkpoint_dict(train_conditioned_specs(data, heads, prof.train, **run))

    ckpt = artifacts.ensure(relpath, config, build, profile=cache_dir(prof),
                            fingerprint=prediction_digest)
    snapshot.unlink(missing_ok=True)
    return load_conditioned(ckpt, vehicles=[h.name for h in heads], device=device)


def conditioned_digest(profile: Profile, leave_out: str | None = None, *,
                       dataset_hash: str | None = None, progress: bool = True) -> str:
    """The prediction digest of a conditioned model (what keys the maps built on it), from
    the cache's metadata; trained first when missing or stale."""
    prof = as_profile(profile)
    dataset_hash = dataset_hash or dataset_digest(prof, progress=progress)
    relpath = conditioned_relpath(leave_out, prof.conditioned.generated_vehicles,
                                  prof.train.inputs)
    config = conditioned_config(prof, None, leave_out, dataset_hash=dataset_hash)
    if not artifacts.is_fresh(relpath, config, profile=cache_dir(prof)):
        ensure_conditioned_model(prof, ensure_dataset(prof, progress=progress), leave_out,
                                 dataset_hash=dataset_hash, progress=progress)
    return artifacts.stored_digest(relpath, profile=cache_dir(prof))


def ensure_conditioned_costmaps(world: World | str, specs: tuple[VehicleSpec | str, ...],
                                profile: Profile | str | None = None,
                                leave_out: str | None = None, *, progress: bool = True
                                ) -> dict[str, np.ndarray]:
    """{vehicle name: cost (K, H, W)} of the conditioned model trained without
    ``leave_out`` for ``specs`` (any vehicles: named, read from a file, generated) on a
    world, by the kit's costmap inference and settings; cached as
    ``costmaps/<world>/conditioned/<model stem>_for_<names>.npz`` (a folder of their own:
    the accuracy stage's key holds the digests of the files in ``costmaps/<world>/``),
    keyed by the BEV map, the model's digest, the specs themselves and the inference
    settings."""
    prof = as_profile(profile)
    specs = tuple(get_vehicle(s) for s in specs)
    names = [s.name for s in specs]
    bev, bev_path = world_bev(world, prof, progress=progress)
    stem = conditioned_stem(leave_out, prof.conditioned.generated_vehicles, prof.train.inputs)
    config = {**costmap_config(prof, bev_path, "conditioned",
                               conditioned_digest(prof, leave_out, progress=progress)),
              "specs": list(specs)}

    def build() -> dict[str, np.ndarray]:
        from dgt_lib.learning.training import window_predictor

        net = ensure_conditioned_model(prof, ensure_dataset(prof, progress=progress), leave_out,
                                       progress=progress).model
        heads = net.for_vehicles(specs)
        cost = directional_costmap(bev, window_predictor(heads, prof.costmap.batch_size),
                                   prof.costmap.n_headings, stride=prof.costmap.stride,
                                   batch_size=prof.costmap.batch_size, progress=progress)
        return dict(zip(names, cost, strict=True))

    key = world_key(world, bev_path)
    return artifacts.ensure(f"costmaps/{key}/conditioned/{stem}_for_{'+'.join(names)}.npz",
                            config, build, profile=cache_dir(prof))
