"""Stage ``dataset``: heading-aligned patches and their locomotion labels, cached
(paper: Self-Supervised Label Generation, Dataset)."""

from __future__ import annotations

from concurrent.futures import Executor

import numpy as np

from dgt_lib.core import artifacts
from dgt_lib.core.config import VEHICLES, Profile, as_profile
from dgt_lib.core.vehicles import get_vehicle
from dgt_lib.perception.dataset import PatchDataset, build_dataset, dataset_summary
from dgt_lib.perception.locomotion import WINDOW_S
from dgt_lib.stages.collect import collect_episodes, ensure_bev
from dgt_lib.stages.paths import cache_dir, data_dir
from dgt_lib.stages.registry import StageOutput

DATASET_RELPATH = "dataset.npz"
"""The dataset artifact under the profile's data directory."""


def ensure_dataset(profile: Profile | str | None = None, *, executor: Executor | None = None,
                   progress: bool = True) -> PatchDataset:
    """The self-supervised dataset of a profile, cached as ``dataset.npz``.

    Builds (through the cache) the episodes and the training world's BEV first.
    The cache key covers the collection and world configuration, the vehicles and
    the BEV map itself.
    """
    prof = as_profile(profile)
    bev = ensure_bev("training", prof, executor=executor, progress=progress)
    config = {"collect": prof.collect, "worlds": prof.worlds, "seed": prof.seed,
              "vehicles": [get_vehicle(v) for v in VEHICLES], "window_s": WINDOW_S,
              "bev": bev.channels, "bev_observed": bev.observed}

    def build() -> dict[str, np.ndarray]:
        episodes = collect_episodes(prof, executor=executor, progress=progress)
        return build_dataset(episodes, bev, prof.collect, seed=prof.seed).to_arrays()

    return PatchDataset.from_arrays(artifacts.ensure(DATASET_RELPATH, config, build,
                                                     profile=cache_dir(prof)))


def stage_dataset(profile: Profile) -> StageOutput:
    """``dgt reproduce`` stage: the patch–label dataset."""
    ds = ensure_dataset(profile)
    return StageOutput([data_dir(profile) / DATASET_RELPATH], dataset_summary(ds))
