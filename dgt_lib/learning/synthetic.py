"""Synthetic patches whose labels follow slope and roughness differently per vehicle: data
for tests, benchmarks and teaching that needs no simulator (not the paper's data)."""

from __future__ import annotations

import numpy as np

from dgt_lib.core.config import VEHICLES
from dgt_lib.learning.model import N_CHANNELS
from dgt_lib.perception.dataset import PatchDataset, split_by_trajectory

SYNTHETIC_MAX_SLOPE = {"jeep": 0.45, "vw_van": 0.25, "mercedes_van": 0.2, "carla_cola": 0.1}
"""Synthetic rule: the uphill slope (rise/run) at which a vehicle's L falls to 0.5."""


SYNTHETIC_ROUGHNESS_SCALE = {"jeep": 0.6, "vw_van": 0.4, "mercedes_van": 0.15, "carla_cola": 0.3}
"""Synthetic rule: roughness σ_H (m) that multiplies a vehicle's L by e^-1."""


def plane_patches(slope: np.ndarray, rough: np.ndarray, rng: np.random.Generator
                  ) -> np.ndarray:
    """Patches (N, 6, 22, 7) float16 of tilted planes: forward slope ``slope`` (N,)
    [rise/run, positive = uphill: the height rises toward row 0], roughness ``rough`` (N,)
    [m] in H̄ and σ_H, ‖∇H̄‖ ≈ |slope|, random uniform colours, a random base height."""
    n = len(slope)
    rows = (21 - np.arange(22)) * 0.4  # (22,) distance behind the patch's front row, m
    patches = np.empty((n, N_CHANNELS, 22, 7), dtype=np.float16)
    patches[:, 0:3] = np.clip(rng.uniform(0.2, 0.6, (n, 3, 1, 1))
                              + rng.normal(0, 0.05, (n, 3, 22, 7)), 0, 1)
    height = (slope[:, None] * rows[None, :])[:, :, None] + rng.uniform(-2, 2, (n, 1, 1))
    patches[:, 3] = height + rough[:, None, None] * rng.normal(0, 0.3, (n, 22, 7))
    patches[:, 4] = rough[:, None, None] * (1 + rng.normal(0, 0.1, (n, 22, 7)))
    patches[:, 5] = np.abs(slope)[:, None, None] + rng.normal(0, 0.02, (n, 22, 7))
    return patches


def synthetic_dataset(
    n_per_vehicle: tuple[int, int, int, int] = (300, 100, 100, 20),
    seed: int = 0,
    patches_per_trajectory: int = 10,
) -> PatchDataset:
    """Synthetic patches whose label follows slope and roughness differently per vehicle.

    Each patch is a plane of forward slope s ∈ [−0.6, 0.6] (positive = uphill:
    the height rises toward row 0) with roughness σ ∈ [0, 0.4] m, random colours.
    Vehicle v's label is L_v = sigmoid((s_max,v − s)/0.05) · exp(−σ / r_v) plus
    noise (±0.02), clipped to [0, 1], with ``SYNTHETIC_MAX_SLOPE`` and
    ``SYNTHETIC_ROUGHNESS_SCALE``. Split 70/15/15 by trajectory (groups of
    ``patches_per_trajectory``). Not data from the simulator: for tests and speed.
    """
    rng = np.random.default_rng(seed)
    n = int(sum(n_per_vehicle))
    vehicle = np.repeat(np.arange(len(VEHICLES), dtype=np.int8), n_per_vehicle)
    slope = rng.uniform(-0.6, 0.6, n)
    rough = rng.uniform(0.0, 0.4, n)
    patches = plane_patches(slope, rough, rng)
    s_max = np.array([SYNTHETIC_MAX_SLOPE[v] for v in VEHICLES])[vehicle]
    r_v = np.array([SYNTHETIC_ROUGHNESS_SCALE[v] for v in VEHICLES])[vehicle]
    labels = np.exp(-rough / r_v) / (1 + np.exp((slope - s_max) / 0.05))
    labels = np.clip(labels + rng.normal(0, 0.02, n), 0, 1).astype(np.float32)
    trajectory = (np.arange(n) // patches_per_trajectory).astype(np.int32)
    # keep each trajectory within one vehicle
    trajectory = (trajectory + vehicle.astype(np.int32) * (n + 1)).astype(np.int32)
    pose = np.column_stack([rng.uniform(0, 100, (n, 2)), rng.uniform(0, 2 * np.pi, n)])
    return PatchDataset(
        patches=patches, observed=np.ones((n, 22, 7), dtype=bool), labels=labels,
        vehicle=vehicle, trajectory=trajectory, pose=pose.astype(np.float32),
        split=split_by_trajectory(trajectory, vehicle, seed=seed),
    )
