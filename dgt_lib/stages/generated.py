"""The procedurally generated training vehicles of the vehicle-conditioned network, through
the cache (docs/vehicles.md → Training the network on generated vehicles).

``conditioned.generated_vehicles`` = N > 0 adds N vehicles
(:func:`~dgt_lib.core.vehicle_generator.generated_vehicles` drawn by the run seed: within and
a little beyond the four named ones) to the conditioned network's training, and nothing
else: the named vehicles stay the experiments' vehicles, and every other artifact keeps its
key. Each generated vehicle is a MuJoCo vehicle driven on the training world by the named
vehicles' episode rules (:func:`~dgt_lib.stages.collect.collect_jobs`: the run's seed,
the same collection settings, resumable), :func:`generated_episodes` runs each, stored as
``episodes/generated/<name>_<index>.npz`` and keyed by the spec itself. Their patches are
cut from the training world's BEV map — the named vehicles' map, which their frames do not
enter — and labelled by the same code
(:func:`~dgt_lib.perception.dataset.build_dataset`), split 70/15/15 by run per vehicle:
``generated/dataset_<N>.npz``.

A conditioned model trained without a named vehicle skips the generated vehicles that are
near copies of it (:func:`training_generated`).
"""

from __future__ import annotations

from concurrent.futures import Executor

import numpy as np

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, Profile, as_profile
from dgt_lib.core.vehicle_generator import generated_vehicles
from dgt_lib.core.vehicle_spec import VehicleSpec
from dgt_lib.perception.bev import BEVMap
from dgt_lib.perception.dataset import PatchDataset, build_dataset
from dgt_lib.perception.episodes import Episode
from dgt_lib.perception.locomotion import WINDOW_S
from dgt_lib.stages.collect import collect_jobs, ensure_bev
from dgt_lib.stages.paths import cache_dir

NEAR_COPY_FRACTION = 0.5
"""A generated vehicle nearer to a left-out named vehicle than this fraction of that
vehicle's distance to its nearest other named vehicle is a near copy of it
(:func:`training_generated`)."""


def profile_generated(profile: Profile | str | None) -> list[VehicleSpec]:
    """The run's N generated vehicles ``gen_00`` … (N = ``conditioned.generated_vehicles``,
    drawn by the run seed; the first k are the same for every N ≥ k)."""
    prof = as_profile(profile)
    return generated_vehicles(prof.conditioned.generated_vehicles, seed=prof.seed)


def generated_episodes(profile: Profile | str | None) -> int:
    """Runs per generated vehicle: the fewest of any named vehicle that is driven
    (``collect.episodes``), so no generated vehicle outweighs a named one."""
    return min(n for n in as_profile(profile).collect.episodes if n > 0)


def generated_episode_relpath(name: str, index: int) -> str:
    """``episodes/generated/<name>_<index>.npz``: apart from the named vehicles' runs."""
    return f"episodes/generated/{name}_{index:04d}.npz"


def collect_generated(profile: Profile | str | None = None, *,
                      executor: Executor | None = None, progress: bool = True
                      ) -> list[Episode]:
    """Every generated vehicle's runs on the training world, by vehicle then index, each
    loaded from its artifact or driven (the named vehicles' rules and executors)."""
    prof = as_profile(profile)
    jobs = [(s, i) for s in profile_generated(prof) for i in range(generated_episodes(prof))]
    return collect_jobs(prof, jobs, generated_episode_relpath, executor=executor,
                        progress=progress, desc=f"generated episodes ({prof.name})")


def generated_dataset_relpath(profile: Profile | str | None) -> str:
    """``generated/dataset_<N>.npz`` under the run's data directory."""
    return f"generated/dataset_{as_profile(profile).conditioned.generated_vehicles}.npz"


def _generated_dataset_config(prof: Profile, bev: BEVMap) -> dict[str, object]:
    """The generated dataset's cache key: the named dataset's
    (:func:`~dgt_lib.stages.dataset.ensure_dataset`) with the generated specs and runs."""
    return {"collect": prof.collect, "worlds": prof.worlds, "seed": prof.seed,
            "vehicles": profile_generated(prof), "episodes": generated_episodes(prof),
            "window_s": WINDOW_S, "bev": bev.channels, "bev_observed": bev.observed}


def ensure_generated_dataset(profile: Profile | str | None = None, *,
                             executor: Executor | None = None, progress: bool = True
                             ) -> PatchDataset:
    """The generated vehicles' patches and labels (``vehicle``: the index among
    :func:`profile_generated`), cached; their runs are collected first if needed."""
    prof = as_profile(profile)
    if prof.conditioned.generated_vehicles < 1:
        raise ValueError("conditioned.generated_vehicles is 0: no generated vehicles")
    bev = ensure_bev("training", prof, executor=executor, progress=progress)

    def build() -> dict[str, np.ndarray]:
        episodes = collect_generated(prof, executor=executor, progress=progress)
        names = [s.name for s in profile_generated(prof)]
        return build_dataset(episodes, bev, prof.collect, seed=prof.seed,
                             vehicles=names).to_arrays()

    return PatchDataset.from_arrays(artifacts.ensure(
        generated_dataset_relpath(prof), _generated_dataset_config(prof, bev), build,
        profile=cache_dir(prof), fingerprint=artifacts.config_hash))


def generated_digest(profile: Profile | str | None = None, *, progress: bool = True) -> str:
    """The generated dataset's fingerprint (a hash of its arrays), from the cache's
    metadata; built first when missing or stale."""
    prof = as_profile(profile)
    bev = ensure_bev("training", prof, progress=progress)
    digest = artifacts.fresh_fingerprint(generated_dataset_relpath(prof),
                                         _generated_dataset_config(prof, bev),
                                         profile=cache_dir(prof))
    return digest or artifacts.config_hash(
        ensure_generated_dataset(prof, progress=progress).to_arrays())


def training_generated(profile: Profile | str | None, leave_out: str | None
                       ) -> list[VehicleSpec]:
    """The generated vehicles a conditioned model trained without ``leave_out`` learns
    from: all of them, except, with a vehicle left out, its near copies (spec vectors
    normalised by the four named vehicles' spread, :data:`NEAR_COPY_FRACTION`): a driven
    near copy would let the network see the vehicle it is to predict unseen."""
    from dgt_lib.beyond.conditioned import spec_statistics, spec_vector  # torch

    specs = profile_generated(profile)
    if leave_out is None or not specs:
        return specs
    mean, std = spec_statistics(VEHICLES)

    def norm(v: VehicleSpec | str) -> np.ndarray:
        return (spec_vector(v) - mean) / std

    held = norm(leave_out)
    nearest = min(float(np.linalg.norm(norm(v) - held)) for v in VEHICLES if v != leave_out)
    return [s for s in specs
            if float(np.linalg.norm(norm(s) - held)) >= NEAR_COPY_FRACTION * nearest]


def combined_dataset(named: PatchDataset, seen: tuple[str, ...], generated: PatchDataset,
                     all_generated: list[str], used: list[str]) -> PatchDataset:
    """The named vehicles ``seen`` and the generated vehicles ``used`` in one dataset whose
    ``vehicle`` is the column among ``seen + used`` (what
    :func:`~dgt_lib.beyond.conditioned.spec_training_set` reads); each sample keeps its
    split, the generated runs get trajectory ids after the named ones'."""
    a = named.subset(np.isin(named.vehicle, [VEHICLES.index(v) for v in seen]))
    a.vehicle = np.searchsorted(np.array([VEHICLES.index(v) for v in seen]),
                                a.vehicle).astype(np.int8)
    column = np.full(len(all_generated), -1, dtype=np.int64)  # generated index → column
    column[[all_generated.index(v) for v in used]] = len(seen) + np.arange(len(used))
    b = generated.subset(column[generated.vehicle.astype(np.int64)] >= 0)
    b.vehicle = column[b.vehicle.astype(np.int64)].astype(np.int8)
    b.trajectory = b.trajectory + (int(named.trajectory.max()) + 1 if len(named) else 0)
    return PatchDataset(**{k: np.concatenate([x, y]) for (k, x), y in
                           zip(a.to_arrays().items(), b.to_arrays().values(), strict=True)})
