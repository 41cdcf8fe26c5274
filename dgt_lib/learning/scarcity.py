"""Data scarcity: train with only a fraction of one vehicle's runs (paper: Claim 4,
"especially in cases where vehicle-specific data is limited").

The paper splits each vehicle's data by trajectory; so does the thinning here. Of
``vehicle``'s *training* runs a fraction f is kept — whole runs, never single patches, so
no trajectory is half kept — and the rest leave every split (their ``split`` becomes
:data:`UNUSED`). Validation and test runs stay, so every fraction is scored on the same
held-out runs. The runs kept are a seeded permutation's first ⌈…⌉: a smaller fraction keeps
a subset of a larger one's runs (nested), and the same seed keeps the same runs for the
multi-task and the single-task model.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from dgt_lib.core.config import VEHICLES
from dgt_lib.perception.dataset import TRAIN, PatchDataset

UNUSED = -1
"""``PatchDataset.split`` of a patch whose run was left out: in no split."""


def runs_kept(n_runs: int, fraction: float) -> int:
    """How many of ``n_runs`` training runs a ``fraction`` in (0, 1] keeps: round(f · n),
    at least one."""
    if not 0 < fraction <= 1:
        raise ValueError(f"fraction must be in (0, 1], got {fraction}")
    return max(1, min(n_runs, int(round(fraction * n_runs))))


def kept_training_runs(dataset: PatchDataset, vehicle: str, fraction: float,
                       seed: int) -> np.ndarray:
    """The trajectory ids of ``vehicle``'s training runs that a ``fraction`` keeps
    (sorted), drawn by ``seed`` (nested across fractions)."""
    v = VEHICLES.index(vehicle)
    runs = np.unique(dataset.trajectory[(dataset.vehicle == v) & (dataset.split == TRAIN)])
    if len(runs) == 0:
        raise ValueError(f"{vehicle} has no training runs to thin out")
    order = np.random.default_rng([seed, v, 4]).permutation(len(runs))
    return np.sort(runs[order[:runs_kept(len(runs), fraction)]])


def keep_runs(dataset: PatchDataset, vehicle: str, fraction: float,
              seed: int) -> PatchDataset:
    """``dataset`` with only a ``fraction`` of ``vehicle``'s training runs in the training
    split (:func:`kept_training_runs`); the patches of the others get split
    :data:`UNUSED`. The arrays of patches are shared, not copied."""
    if fraction == 1.0:
        return dataset
    kept = kept_training_runs(dataset, vehicle, fraction, seed)
    dropped = ((dataset.vehicle == VEHICLES.index(vehicle)) & (dataset.split == TRAIN)
               & ~np.isin(dataset.trajectory, kept))
    split = dataset.split.copy()
    split[dropped] = UNUSED
    return replace(dataset, split=split)
