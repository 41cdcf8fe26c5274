"""Stage ``dataset``: heading-aligned patches and their locomotion labels, cached
(paper: Self-Supervised Label Generation, Dataset)."""

from __future__ import annotations

from concurrent.futures import Executor

import numpy as np

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, Profile, as_profile
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.perception.bev import BEVMap
from dgt_lib.perception.dataset import PatchDataset, build_dataset, dataset_summary
from dgt_lib.perception.locomotion import WINDOW_S
from dgt_lib.stages.collect import collect_episodes, ensure_bev
from dgt_lib.stages.output import StageOutput
from dgt_lib.stages.paths import cache_dir, data_dir

DATASET_RELPATH = "dataset.npz"
"""The dataset artifact under the profile's data directory."""


def dataset_fingerprint(dataset: PatchDataset) -> str:
    """A hash of every array of ``dataset``: what keys the models and the slope fit built
    on it (:func:`dataset_digest` reads it from the cache without loading the patches)."""
    return artifacts.config_hash(dataset.to_arrays())


DATASET_FORMAT = 1
"""The version of the stored dataset: bumped by any change that alters its patches."""


def _dataset_config(prof: Profile, bev: BEVMap) -> dict[str, object]:
    """The dataset artifact's cache key: the collection and world configuration, the
    vehicles and the training world's BEV map itself."""
    return {"format": DATASET_FORMAT, "collect": prof.collect, "worlds": prof.worlds,
            "seed": prof.seed, "vehicles": [get_vehicle(v) for v in VEHICLES], "window_s": WINDOW_S,
            "bev": bev.channels, "bev_observed": bev.observed}


def ensure_dataset(profile: Profile | str | None = None, *, executor: Executor | None = None,
                   progress: bool = True) -> PatchDataset:
    """The self-supervised dataset of a profile, cached as ``dataset.npz``.

    Builds (through the cache) the episodes and the training world's BEV first.
    The cache key covers the collection and world configuration, the vehicles and
    the BEV map itself; the metadata records its :func:`dataset_fingerprint`.
    """
    prof = as_profile(profile)
    bev = ensure_bev("training", prof, executor=executor, progress=progress)

    def build() -> dict[str, np.ndarray]:
        episodes = collect_episodes(prof, executor=executor, progress=progress)
        return build_dataset(episodes, bev, prof.collect, seed=prof.seed).to_arrays()

    return PatchDataset.from_arrays(artifacts.ensure(
        DATASET_RELPATH, _dataset_config(prof, bev), build, profile=cache_dir(prof),
        fingerprint=artifacts.config_hash))  # of the arrays: = dataset_fingerprint


def dataset_digest(profile: Profile | str | None = None, *, executor: Executor | None = None,
                   progress: bool = True) -> str:
    """:func:`dataset_fingerprint` of the profile's dataset, read from the cache's metadata
    when the dataset is cached (its 60,000 ``paper`` patches are not loaded: a cached
    ``dgt plan`` checks its maps' keys quickly); built first if it is not."""
    prof = as_profile(profile)
    bev = ensure_bev("training", prof, executor=executor, progress=progress)
    digest = artifacts.fresh_fingerprint(DATASET_RELPATH, _dataset_config(prof, bev),
                                         profile=cache_dir(prof))
    return digest or dataset_fingerprint(ensure_dataset(prof, executor=executor,
                                                        progress=progress))


def stage_dataset(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: the patch–label dataset."""
    ds = ensure_dataset(profile)
    return StageOutput([data_dir(profile) / DATASET_RELPATH], dataset_summary(ds))
