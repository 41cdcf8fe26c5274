"""The self-supervised dataset: heading-aligned patches paired with locomotion labels.

Paper: Self-Supervised Label Generation and Experimental Protocol. Each sample is a
``(6, 22, 7)`` BEV patch P (channels R, G, B, H̄, σ_H, ‖∇H̄‖; forward = row 0),
its label L_v(t_P) ∈ [0, 1], the vehicle v (index into ``config.VEHICLES``), the
trajectory it came from and the pose (x, y, θ) it was cut at. The data of each
vehicle is split 70/15/15 into train/validation/test **by trajectory**, so no
trajectory has patches in two partitions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import VEHICLES

TRAIN, VAL, TEST = 0, 1, 2
SPLIT_NAMES = ("train", "val", "test")
SPLIT_FRACTIONS = (0.70, 0.15, 0.15)


@dataclass
class PatchDataset:
    """Patch–label pairs of all vehicles, stored compactly.

    patches: (N, 6, 22, 7) float16. observed: (N, 22, 7) bool (cells seen in the BEV).
    labels: (N,) float32 locomotion L ∈ [0, 1]. vehicle: (N,) int8 head index.
    trajectory: (N,) int32 globally unique run id. pose: (N, 3) float32 (x [m], y [m], θ [rad]).
    split: (N,) int8, TRAIN / VAL / TEST.
    """

    patches: np.ndarray
    observed: np.ndarray
    labels: np.ndarray
    vehicle: np.ndarray
    trajectory: np.ndarray
    pose: np.ndarray
    split: np.ndarray

    def __post_init__(self):
        n = len(self.labels)
        for name in ("patches", "observed", "vehicle", "trajectory", "pose", "split"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"PatchDataset.{name} has {len(getattr(self, name))} rows, "
                                 f"labels has {n}")

    def __len__(self) -> int:
        return len(self.labels)

    def subset(self, mask: np.ndarray) -> PatchDataset:
        """The samples where ``mask`` (bool or index array) selects."""
        return PatchDataset(**{k: v[mask] for k, v in self.to_arrays().items()})

    def part(self, split: int | str, vehicle: int | str | None = None) -> PatchDataset:
        """One partition ("train"/"val"/"test" or 0/1/2), optionally of one vehicle."""
        s = SPLIT_NAMES.index(split) if isinstance(split, str) else int(split)
        mask = self.split == s
        if vehicle is not None:
            v = VEHICLES.index(vehicle) if isinstance(vehicle, str) else int(vehicle)
            mask &= self.vehicle == v
        return self.subset(mask)

    def counts(self) -> dict[str, dict[str, int]]:
        """Samples per vehicle and split, e.g. ``counts()["jeep"]["train"]``."""
        return {
            name: {sn: int(np.sum((self.vehicle == v) & (self.split == s)))
                   for s, sn in enumerate(SPLIT_NAMES)}
            for v, name in enumerate(VEHICLES)
        }

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The arrays, for ``artifacts.save`` as ``.npz``."""
        return {k: getattr(self, k) for k in
                ("patches", "observed", "labels", "vehicle", "trajectory", "pose", "split")}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> PatchDataset:
        return cls(**{k: arrays[k] for k in
                      ("patches", "observed", "labels", "vehicle", "trajectory", "pose", "split")})


def split_by_trajectory(
    trajectory: np.ndarray,
    vehicle: np.ndarray,
    seed: int = 0,
    fractions: tuple[float, float, float] = SPLIT_FRACTIONS,
) -> np.ndarray:
    """Assign each sample to train/val/test so that every trajectory lies in one partition.

    Per vehicle, its trajectories are shuffled (seeded) and cut at the cumulative
    ``fractions`` of trajectory count (paper: 70/15/15 by trajectory). Returns
    (N,) int8 with TRAIN / VAL / TEST.
    """
    if not np.isclose(sum(fractions), 1.0):
        raise ValueError(f"split fractions must sum to 1, got {fractions}")
    rng = np.random.default_rng(seed)
    split = np.full(len(trajectory), TRAIN, dtype=np.int8)
    for v in np.unique(vehicle):
        trajs = np.unique(trajectory[vehicle == v])
        rng.shuffle(trajs)
        n = len(trajs)
        n_train = int(round(fractions[0] * n))
        n_val = int(round(fractions[1] * n))
        if n >= 3:  # keep every partition non-empty when possible
            n_train = min(max(n_train, 1), n - 2)
            n_val = min(max(n_val, 1), n - n_train - 1)
        part = np.full(n, TEST, dtype=np.int8)
        part[:n_train] = TRAIN
        part[n_train : n_train + n_val] = VAL
        lookup = dict(zip(trajs.tolist(), part.tolist(), strict=True))
        idx = np.flatnonzero(vehicle == v)
        split[idx] = [lookup[t] for t in trajectory[idx].tolist()]
    return split
