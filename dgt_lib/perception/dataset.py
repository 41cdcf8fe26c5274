"""The self-supervised dataset: heading-aligned patches paired with locomotion labels.

Paper: Self-Supervised Label Generation and Experimental Protocol. Each sample is a
``(6, 22, 7)`` BEV patch P (channels R, G, B, H̄, σ_H, ‖∇H̄‖; forward = row 0),
its label L_v(t_P) ∈ [0, 1], the vehicle v (index into ``config.VEHICLES``), the
trajectory it came from and the pose (x, y, θ) it was cut at. The data of each
vehicle is split 70/15/15 into train/validation/test **by trajectory**, so no
trajectory has patches in two partitions.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from dgt_lib.core.config import VEHICLES, CollectConfig

if TYPE_CHECKING:  # heavy modules, imported where they are used
    from dgt_lib.perception.bev import BEVMap
    from dgt_lib.perception.episodes import Episode

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


# ----------------------------------------------------------------------------- building
# Patches along every collection run, paired with the run's locomotion label
# (paper: Self-Supervised Label Generation). The heavy imports (simulator, worlds)
# happen inside the functions so that ``import dgt_lib.perception.dataset`` stays light.


def label_window(times_s: np.ndarray, at_s: np.ndarray, window_s: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Start and end [s] of the label window of each query time: centred, shifted to
    lie inside the run (the rule of :func:`dgt_lib.perception.locomotion.locomotion_signal`)."""
    t = np.asarray(times_s, dtype=np.float64)
    span = min(window_s, t[-1] - t[0])
    start = np.clip(np.asarray(at_s, dtype=np.float64) - 0.5 * span, t[0], t[-1] - span)
    return start, start + span


def patch_times(times_s: np.ndarray, valid: np.ndarray, interval_s: float, start_s: float,
                window_s: float) -> np.ndarray:
    """Times [s] at which to cut patches along one run.

    Every ``interval_s`` from ``start_s`` (no patches while the vehicle accelerates
    from rest) to the end of the run, except where the label window touches an
    invalid sample (``valid`` False: a simulator glitch,
    :data:`~dgt_lib.perception.locomotion.MAX_ANGULAR_RATE_DPS`).
    times_s: (T,) [s]; valid: (T,) bool. Returns (M,) float64, possibly empty.
    """
    t = np.asarray(times_s, dtype=np.float64)
    if not interval_s > 0:
        raise ValueError(f"interval_s must be > 0, got {interval_s}")
    if len(t) < 2 or t[-1] < start_s:
        return np.zeros(0)
    at = np.arange(start_s, t[-1] + 1e-9, interval_s)
    lo, hi = label_window(t, at, window_s)
    bad = np.concatenate([[0], np.cumsum(~np.asarray(valid, dtype=bool))])
    first = np.searchsorted(t, lo, side="left")  # samples with lo ≤ t ≤ hi
    last = np.searchsorted(t, hi, side="right")
    return at[bad[last] - bad[first] == 0]


def pose_at(times_s: np.ndarray, pose: np.ndarray, at_s: np.ndarray) -> np.ndarray:
    """(M, 3) poses (x, y, yaw ∈ [0, 2π)) interpolated at ``at_s`` (yaw unwrapped first)."""
    t = np.asarray(times_s, dtype=np.float64)
    p = np.asarray(pose, dtype=np.float64)
    yaw = np.unwrap(p[:, 2])
    return np.stack([np.interp(at_s, t, p[:, 0]), np.interp(at_s, t, p[:, 1]),
                     np.mod(np.interp(at_s, t, yaw), 2 * np.pi)], axis=1)


ARTIFACT_ENDS = ("off_map", "diverged")
"""End reasons that are simulation artifacts, not terrain: falling off the map's
edge, a diverged solver. No patch is cut in their last :data:`ARTIFACT_END_S`."""
ARTIFACT_END_S = 2.0  # [s]


def episode_patches(episode: Episode, bev: BEVMap, config: CollectConfig | None = None,
                    window_s: float | None = None) -> dict[str, np.ndarray]:
    """Patches of one run (a :class:`dgt_lib.perception.episodes.Episode`) cut from ``bev`` with
    their labels L_v(t_P) (paper: "each patch P extracted at time t_P is paired with
    L_v(t_P)"), at :func:`patch_times` of the run; none in the last 2 s of a run that fell
    off the map or diverged (:data:`ARTIFACT_ENDS`).

    Returns ``times`` (M,), ``pose`` (M, 3), ``patches`` (M, 6, 22, 7) float32,
    ``observed`` (M, 22, 7) bool and ``labels`` (M,) float32 in [0, 1].
    """
    from dgt_lib.perception.locomotion import WINDOW_S, locomotion_signal
    from dgt_lib.perception.patches import extract_patches

    cfg = config or CollectConfig()
    w = WINDOW_S if window_s is None else window_s
    t = np.asarray(episode.time_s, dtype=np.float64)
    valid = np.asarray(episode.valid, dtype=bool)
    if episode.end_reason in ARTIFACT_ENDS:  # the last moments show the map edge / a glitch
        valid = valid & (t <= t[-1] - ARTIFACT_END_S)
    at = t[0] + patch_times(t - t[0], valid, cfg.patch_interval_s, cfg.patch_start_s, w)
    if len(at) == 0:
        return {"times": np.zeros(0), "pose": np.zeros((0, 3)),
                "patches": np.zeros((0, 6, 22, 7), np.float32),
                "observed": np.zeros((0, 22, 7), bool), "labels": np.zeros(0, np.float32)}
    xy_yaw = np.asarray(episode.pose, dtype=np.float64)
    pose = pose_at(t, xy_yaw, at)
    labels = locomotion_signal(t, xy_yaw[:, :2], window_s=w, u=cfg.speed_mps, at_s=at)
    patches, observed = extract_patches(bev, pose)
    return {"times": at, "pose": pose, "patches": patches, "observed": observed,
            "labels": np.asarray(labels).astype(np.float32)}


def build_dataset(episodes: Sequence[Episode], bev: BEVMap,
                  config: CollectConfig | None = None, seed: int = 0,
                  vehicles: Sequence[str] = VEHICLES) -> PatchDataset:
    """The :class:`PatchDataset` of a list of episodes on the map ``bev``.

    The k-th episode gets trajectory id k (unique across vehicles); the split is
    70/15/15 by trajectory per vehicle (:func:`split_by_trajectory`, seeded). A sample's
    ``vehicle`` is its episode's vehicle's index in ``vehicles`` (default the named four;
    the generated training vehicles, :mod:`dgt_lib.stages.generated`, pass their names).
    """
    parts = []
    for k, ep in enumerate(episodes):
        s = episode_patches(ep, bev, config)
        m = len(s["labels"])
        parts.append((s, np.full(m, list(vehicles).index(ep.vehicle), np.int8),
                      np.full(m, k, np.int32)))
    if not parts:
        raise ValueError("build_dataset needs at least one episode")
    patches = np.concatenate([p[0]["patches"] for p in parts]).astype(np.float16)
    vehicle = np.concatenate([p[1] for p in parts])
    trajectory = np.concatenate([p[2] for p in parts])
    return PatchDataset(
        patches=patches,
        observed=np.concatenate([p[0]["observed"] for p in parts]),
        labels=np.concatenate([p[0]["labels"] for p in parts]).astype(np.float32),
        vehicle=vehicle, trajectory=trajectory,
        pose=np.concatenate([p[0]["pose"] for p in parts]).astype(np.float32),
        split=split_by_trajectory(trajectory, vehicle, seed=seed),
    )


def dataset_summary(ds: PatchDataset) -> str:
    """One line: patches per vehicle and split, trajectories and mean label."""
    parts = []
    for v, name in enumerate(VEHICLES):
        sel = ds.vehicle == v
        c = [int(np.sum(sel & (ds.split == s))) for s in range(3)]
        n_traj = len(np.unique(ds.trajectory[sel]))
        mean_l = float(ds.labels[sel].mean()) if sel.any() else float("nan")
        parts.append(f"{name} {int(sel.sum())} ({c[0]}/{c[1]}/{c[2]}, {n_traj} runs, "
                     f"mean L {mean_l:.2f})")
    return f"{len(ds)} patches (train/val/test): " + "; ".join(parts)
